//! Random access to the records of an NPY stream in a file: an index of its
//! arrays (headers only, payloads skipped), then any record by a seek and
//! one read. What a tool that needs scattered records (the real records the
//! pairs name) uses instead of holding the file in memory.

use std::collections::{BTreeSet, HashMap};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

use super::header::Dtype;
use super::reader::{ArrayExtent, NpyReader};
use crate::error::{DemError, Result};
use crate::format::{canonicalize, Dem, RECORD_LEN};

/// The arrays of an NPY file and an open handle to read records from.
pub struct RecordIndex {
    path: String,
    file: File,
    arrays: Vec<ArrayExtent>,
    total: u64,
}

impl RecordIndex {
    /// Index the file at `path` (not stdin: a pipe cannot seek). Memory is
    /// one entry per array, whatever the records.
    pub fn build(path: &str) -> Result<Self> {
        let open = || File::open(path).map_err(|source| DemError::Open { path: path.into(), source });
        let file = open()?;
        let len = file.metadata().map_err(|e| DemError::io(path, e))?.len();
        let mut rdr = NpyReader::new(file, path, Some(len));
        let mut arrays = Vec::new();
        while let Some(a) = rdr.next_array()? {
            if a.records > 0 {
                arrays.push(a);
            }
        }
        Ok(RecordIndex { path: path.into(), file: open()?, arrays, total: rdr.records_read() })
    }

    /// Records in the file.
    pub fn len(&self) -> u64 {
        self.total
    }

    /// True when the file holds no records.
    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// Record `i`, under the contract's input rules (a NaN height is a
    /// missing cell; an infinity is refused naming the record).
    pub fn get(&mut self, i: u64) -> Result<Dem> {
        let k = self.arrays.partition_point(|a| a.first + a.records <= i);
        let a = *self.arrays.get(k).filter(|a| a.first <= i).ok_or_else(|| {
            DemError::input(self.path.as_str(), format!("record {i} asked for, but the file holds {} records", self.total))
        })?;
        let size = a.dtype.size();
        let offset = a.payload + (i - a.first) * (RECORD_LEN * size) as u64;
        let mut bytes = vec![0u8; RECORD_LEN * size];
        self.file.seek(SeekFrom::Start(offset)).map_err(|e| DemError::io(self.path.as_str(), e))?;
        self.file.read_exact(&mut bytes).map_err(|e| DemError::io(self.path.as_str(), e))?;
        let mut d = [0.0f32; RECORD_LEN];
        match a.dtype {
            Dtype::F32 => {
                d.iter_mut().zip(bytes.chunks_exact(4)).for_each(|(v, b)| *v = f32::from_le_bytes(b.try_into().expect("4 bytes")))
            }
            Dtype::F64 => {
                d.iter_mut().zip(bytes.chunks_exact(8)).for_each(|(v, b)| *v = f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
            }
        }
        canonicalize(&mut d).map_err(|reason| DemError::Npy { path: self.path.clone(), record: i, offset, reason })?;
        Ok(d)
    }
}

/// The records of an NPY stream by index: a file through its
/// [`RecordIndex`]; stdin, which cannot seek, read once with only the
/// records `keep` names held.
pub enum ByIndex {
    /// A file, read by seeking.
    Indexed(RecordIndex),
    /// Stdin's kept records, and how many the stream held.
    Held(HashMap<u64, Dem>, u64),
}

impl ByIndex {
    /// Open `path` (`-` for stdin, holding the records `keep` names).
    pub fn open(path: &str, keep: impl Fn(u64) -> bool) -> Result<Self> {
        if path == "-" {
            let (n, held) = super::read_selected(path, keep)?;
            return Ok(ByIndex::Held(held, n));
        }
        Ok(ByIndex::Indexed(RecordIndex::build(path)?))
    }

    /// Records in the stream.
    pub fn len(&self) -> u64 {
        match self {
            ByIndex::Indexed(idx) => idx.len(),
            ByIndex::Held(_, n) => *n,
        }
    }

    /// True when the stream holds no records.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Record `i` (of stdin: one `keep` named).
    pub fn get(&mut self, i: u64) -> Result<Dem> {
        match self {
            ByIndex::Indexed(idx) => idx.get(i),
            ByIndex::Held(m, n) => m
                .get(&i)
                .copied()
                .ok_or_else(|| DemError::input("-", format!("record {i} asked for, but stdin held {n} records and it was not kept"))),
        }
    }

    /// The records `wanted` names, by index.
    pub fn fetch(&mut self, wanted: &BTreeSet<u64>) -> Result<HashMap<u64, Dem>> {
        wanted.iter().map(|&j| self.get(j).map(|d| (j, d))).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::empty_dem;
    use crate::DemCells;

    #[test]
    fn every_record_of_a_stream_of_arrays_reads_as_the_stream_reader_reads_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.npy").to_string_lossy().into_owned();
        let recs: Vec<Dem> = (0..10)
            .map(|i| {
                let mut d = empty_dem();
                d.set_valid(i % 20, i % 5, i as f32 * 0.01);
                d
            })
            .collect();
        // Three arrays back to back (4, 0 and 6 records), as a pipe writes them.
        let mut bytes = Vec::new();
        for part in [&recs[..4], &recs[4..4], &recs[4..]] {
            bytes.extend(crate::npy::header::f32_header(part.len() as u64));
            part.iter().flatten().for_each(|v| bytes.extend(v.to_le_bytes()));
        }
        std::fs::write(&p, &bytes).unwrap();
        let mut idx = RecordIndex::build(&p).unwrap();
        assert_eq!(idx.len(), 10);
        for i in [9, 0, 4, 3, 5] {
            assert_eq!(idx.get(i).unwrap(), recs[i as usize]);
        }
        assert!(idx.get(10).unwrap_err().to_string().contains("record 10 asked for"));
        // A lying header is refused while indexing, naming the file.
        bytes.truncate(bytes.len() - 8);
        std::fs::write(&p, &bytes).unwrap();
        assert!(RecordIndex::build(&p).is_err());
    }
}
