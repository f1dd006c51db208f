//! A plain `.npy` writer for `<f4` arrays of any record shape, streamed:
//! not the contract's DEM stream (no `(21, 5, 2)` shape, NaN allowed, no
//! stdout or pipes), for side outputs such as `dem-synth --emit-maps`'s
//! `maps.npy` of shape `(M, 2, 80, 80)`.
//!
//! The file is written to a temp file beside the target with a reserved
//! v1.0 header ([`f32_array_header`]); [`F32ArrayWriter::finish`] patches the
//! record count into the header and renames the file into place, so memory
//! stays one record and readers never see a partial file. Dropped
//! unfinished (an error on the way), the temp file is removed.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};

use super::header::f32_array_header;
use crate::error::{DemError, Result};
use crate::output::{resolve, temp_beside};

/// A writer of a C-order `<f4` array `(records, record_shape...)`; call
/// [`F32ArrayWriter::finish`] to complete it.
pub struct F32ArrayWriter {
    out: BufWriter<File>,
    temp: tempfile::TempPath,
    path: String,
    record_shape: Vec<u64>,
    record_len: usize,
    records: u64,
}

impl F32ArrayWriter {
    /// Start writing `path` (a regular file, replaced atomically on
    /// [`finish`](Self::finish)) for records of `record_shape`.
    pub fn create(path: &str, record_shape: &[u64]) -> Result<Self> {
        let (file, temp) = temp_beside(path)?.into_parts();
        let mut out = BufWriter::with_capacity(1 << 20, file);
        let mut shape = vec![0];
        shape.extend_from_slice(record_shape);
        out.write_all(&f32_array_header(&shape)).map_err(|e| DemError::io(path, e))?;
        let record_len = record_shape.iter().product::<u64>() as usize;
        Ok(F32ArrayWriter { out, temp, path: path.into(), record_shape: record_shape.to_vec(), record_len, records: 0 })
    }

    /// Records written so far.
    pub fn records_written(&self) -> u64 {
        self.records
    }

    /// Append whole records, C order (`values.len()` a multiple of the
    /// record length; any f32, NaN included).
    pub fn write(&mut self, values: &[f32]) -> Result<()> {
        assert!(
            self.record_len > 0 && values.len().is_multiple_of(self.record_len),
            "{} values are not whole records of {}",
            values.len(),
            self.record_len
        );
        let bytes: std::borrow::Cow<'_, [u8]> = if cfg!(target_endian = "little") {
            bytemuck::cast_slice(values).into()
        } else {
            values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>().into()
        };
        self.out.write_all(&bytes).map_err(|e| DemError::io(self.path.as_str(), e))?;
        self.records += (values.len() / self.record_len) as u64;
        Ok(())
    }

    /// Count `n` records of an empty record shape (a zero in it): the array
    /// `(n, ..., 0, ...)` has no values to write.
    pub fn write_empty(&mut self, n: u64) {
        assert_eq!(self.record_len, 0, "records of {} values are not empty", self.record_len);
        self.records += n;
    }

    /// Patch the record count into the header, flush, and move the file
    /// into place.
    pub fn finish(self) -> Result<()> {
        let F32ArrayWriter { mut out, temp, path, record_shape, records, .. } = self;
        let io_err = |e| DemError::io(path.as_str(), e);
        let mut shape = vec![records];
        shape.extend_from_slice(&record_shape);
        out.flush().map_err(io_err)?;
        out.seek(SeekFrom::Start(0)).map_err(io_err)?;
        out.write_all(&f32_array_header(&shape)).map_err(io_err)?;
        out.flush().map_err(io_err)?;
        drop(out.into_inner().map_err(|e| io_err(e.into_error()))?);
        temp.persist(resolve(&path)).map_err(|e| io_err(e.error))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_counts_the_records_and_data_follows_in_c_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.npy").to_string_lossy().into_owned();
        let mut w = F32ArrayWriter::create(&path, &[2, 3]).unwrap();
        w.write(&[0.0, 1.0, f32::NAN, 3.0, 4.0, 5.0]).unwrap();
        w.write(&[6.0; 12]).unwrap();
        assert_eq!(w.records_written(), 3);
        assert!(!std::path::Path::new(&path).exists(), "no file before finish");
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let header = f32_array_header(&[3, 2, 3]);
        assert_eq!(&bytes[..header.len()], &header[..]);
        let dict = std::str::from_utf8(&bytes[10..header.len()]).unwrap();
        assert!(dict.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 2, 3), }"), "{dict}");
        assert_eq!(bytes.len(), header.len() + 18 * 4);
        let at = |k: usize| f32::from_le_bytes(bytes[header.len() + 4 * k..][..4].try_into().unwrap());
        assert!(at(2).is_nan());
        assert_eq!((at(1), at(5), at(17)), (1.0, 5.0, 6.0));
    }

    #[test]
    fn dropped_unfinished_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.npy").to_string_lossy().into_owned();
        let mut w = F32ArrayWriter::create(&path, &[4]).unwrap();
        w.write(&[1.0; 4]).unwrap();
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn header_length_does_not_depend_on_the_count() {
        for shape in [[0u64, 2, 80, 80], [u64::MAX, 2, 80, 80]] {
            let h = f32_array_header(&shape);
            assert_eq!(h.len(), 128);
            assert_eq!(h.len() % 64, 0);
            assert_eq!(*h.last().unwrap(), b'\n');
        }
        assert!(String::from_utf8_lossy(&f32_array_header(&[7])).contains("'shape': (7,), }"));
    }
}
