//! A labels CSV read a row at a time beside its records, to be cut
//! (dem-split) or joined (dem-cat) with them. Each row is kept as the bytes
//! it was written in (extra columns, quoting, spacing, line ends); only its
//! `index`, the first field, is rewritten to count in the file written.
//! Every row is checked as the tools check labels
//! ([`crate::table::read_labels`]: header, terrain, numbers, index order),
//! so labels written from it are read by every tool that reads the input's.

use std::io::{BufRead, Write};

use crate::table::{self, Label};
use crate::DemError;

const UNBALANCED: &str = "unbalanced quotes: a quoted field is not closed, or a quote stands inside a field \
that does not start with one (quote the whole field, a quote inside it as \"\")";

/// A labels CSV being read row by row.
pub struct LabelsReader {
    path: String,
    src: Box<dyn BufRead>,
    /// The header line, as written (line end included).
    header: Vec<u8>,
    headers: csv::StringRecord,
    /// Lines read so far (the next record starts on `line + 1`).
    line: u64,
    /// Data rows read so far.
    rows: u64,
}

/// One data row: its bytes and where its first field ends.
pub struct RawRow {
    bytes: Vec<u8>,
    first_end: usize,
}

impl LabelsReader {
    /// Open `path` (`-` for stdin) and check its header: it must start with
    /// `index,terrain`.
    pub fn open(path: &str) -> Result<Self, DemError> {
        let src: Box<dyn BufRead> = Box::new(std::io::BufReader::new(table::open_input(path)?));
        let mut r = LabelsReader { path: path.into(), src, header: Vec::new(), headers: csv::StringRecord::new(), line: 0, rows: 0 };
        let Some((line, header)) = r.next_record()? else {
            return Err(DemError::Table {
                path: path.into(),
                line: 1,
                reason: "is empty: a labels CSV starts with the header index,terrain".into(),
            });
        };
        let fields = r.parse(line, &header)?;
        if fields.get(0) != Some("index") || fields.get(1) != Some("terrain") {
            return Err(r.bad(line, format!("header must start with index,terrain, found {}", fields.iter().collect::<Vec<_>>().join(","))));
        }
        r.header = header;
        r.headers = fields;
        Ok(r)
    }

    /// The header line as written, ending in a line end.
    pub fn header(&self) -> Vec<u8> {
        with_line_end(self.header.clone())
    }

    /// Data rows read so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The header's column names, trimmed.
    pub fn columns(&self) -> Vec<&str> {
        self.headers.iter().collect()
    }

    fn bad(&self, line: u64, reason: String) -> DemError {
        DemError::Table { path: self.path.clone(), line, reason }
    }

    /// The next CSV record's bytes and the line it starts on, skipping
    /// empty lines (as the CSV reader does). A record ends at a line end
    /// outside quotes.
    fn next_record(&mut self) -> Result<Option<(u64, Vec<u8>)>, DemError> {
        let mut rec = Vec::new();
        let mut start = 0;
        loop {
            let before = rec.len();
            let n = self.src.read_until(b'\n', &mut rec).map_err(|e| DemError::io(self.path.as_str(), e))?;
            if n == 0 {
                if rec.is_empty() {
                    return Ok(None);
                }
                return Err(self.bad(start, UNBALANCED.into()));
            }
            self.line += 1;
            if before == 0 {
                if matches!(&rec[..], b"\n" | b"\r\n") {
                    rec.clear();
                    continue;
                }
                start = self.line;
            }
            if rec.iter().filter(|&&b| b == b'"').count() % 2 == 0 {
                return Ok(Some((start, rec)));
            }
        }
    }

    /// The fields of one record's bytes, as the tools' CSV reader sees them
    /// (trimmed); exactly one record.
    fn parse(&self, line: u64, bytes: &[u8]) -> Result<csv::StringRecord, DemError> {
        let mut rdr = csv::ReaderBuilder::new().has_headers(false).trim(csv::Trim::All).flexible(true).from_reader(bytes);
        let mut rec = csv::StringRecord::new();
        let mut extra = csv::StringRecord::new();
        let one = rdr.read_record(&mut rec).map_err(|e| self.bad(line, e.to_string()))?;
        let more = rdr.read_record(&mut extra).map_err(|e| self.bad(line, e.to_string()))?;
        if !one || more {
            return Err(self.bad(line, UNBALANCED.into()));
        }
        Ok(rec)
    }

    /// The next data row, checked (fields, values, index in order); None
    /// at the end of the file.
    pub fn next_row(&mut self) -> Result<Option<RawRow>, DemError> {
        let Some((line, bytes)) = self.next_record()? else { return Ok(None) };
        let rec = self.parse(line, &bytes)?;
        if rec.len() != self.headers.len() {
            return Err(self.bad(line, format!("{} fields where the header has {}", rec.len(), self.headers.len())));
        }
        let label: Label = rec.deserialize(Some(&self.headers)).map_err(|e| {
            let reason = match e.kind() {
                csv::ErrorKind::Deserialize { err, .. } => err.to_string(),
                _ => e.to_string(),
            };
            self.bad(line, reason)
        })?;
        if label.index != self.rows {
            return Err(self.bad(line, format!("index {} out of order (expected {})", label.index, self.rows)));
        }
        self.rows += 1;
        Ok(Some(RawRow { first_end: first_field_end(&bytes), bytes }))
    }
}

/// Where the first field of a record ends: at the first comma outside quotes.
fn first_field_end(bytes: &[u8]) -> usize {
    let mut quoted = false;
    for (i, &b) in bytes.iter().enumerate() {
        match b {
            b'"' => quoted = !quoted,
            b',' if !quoted => return i,
            _ => {}
        }
    }
    bytes.len()
}

fn with_line_end(mut bytes: Vec<u8>) -> Vec<u8> {
    if bytes.last() != Some(&b'\n') {
        bytes.push(b'\n');
    }
    bytes
}

/// Write `row` with `index` as its first field, the rest as it was.
pub fn write_row(out: &mut impl Write, row: &RawRow, index: u64) -> std::io::Result<()> {
    write!(out, "{index}")?;
    let rest = &row.bytes[row.first_end..];
    out.write_all(rest)?;
    if rest.last() != Some(&b'\n') {
        out.write_all(b"\n")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn split_rows(text: &str) -> Result<(Vec<u8>, Vec<String>), DemError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("l.csv").to_string_lossy().into_owned();
        std::fs::write(&p, text).unwrap();
        let mut r = LabelsReader::open(&p)?;
        let mut rows = Vec::new();
        while let Some(row) = r.next_row()? {
            let mut out = Vec::new();
            write_row(&mut out, &row, 10 + rows.len() as u64).unwrap();
            rows.push(String::from_utf8(out).unwrap());
        }
        Ok((r.header(), rows))
    }

    #[test]
    fn rows_keep_their_bytes_but_the_index() {
        let (h, rows) = split_rows("index,terrain,note,x\r\n0,flat,\"a, \"\"b\"\"\nc\",1.5\r\n\n\" 1 \", pallet ,plain,2").unwrap();
        assert_eq!(h, b"index,terrain,note,x\r\n");
        assert_eq!(rows, ["10,flat,\"a, \"\"b\"\"\nc\",1.5\r\n", "11, pallet ,plain,2\n"]);
    }

    #[test]
    fn bad_rows_name_their_line() {
        let e = |t: &str| split_rows(t).unwrap_err().to_string();
        assert!(e("index,terrain\n0,flat\n1,lava\n").contains("line 3"), "{}", e("index,terrain\n0,flat\n1,lava\n"));
        assert!(e("index,terrain\n1,flat\n").contains("index 1 out of order"));
        assert!(e("index,terrain\n0,flat,x\n").contains("3 fields where the header has 2"));
        assert!(e("index,terrain\n0,fl\"at\n1,flat\n").contains("line 2: unbalanced quotes"));
        assert!(e("index,terrain\n0,fl\"at\n1,\"fl\"at\"\n").contains("line 2: unbalanced quotes"));
        assert!(e("index,terrain\n0,\"flat\n").contains("line 2: unbalanced quotes"));
        assert!(e("idx,terrain\n").contains("line 1: header must start with index,terrain"));
        assert!(e("").contains("is empty"));
    }
}
