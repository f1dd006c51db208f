//! The `.npy` header: parse what numpy writes (v1, v2, v3) and write exactly
//! the bytes `numpy.save` writes for a `(n, 21, 5, 2)` `<f4` array.
//!
//! Layout: magic `\x93NUMPY`, major, minor, header length (u16 LE for v1,
//! u32 LE for v2/v3), then a Python dict literal padded with spaces and a
//! newline so the data starts on a 64-byte boundary.

use crate::format::{CHANNELS, COLS, ROWS};

/// The six magic bytes of every `.npy` file.
pub const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Element type of an array we accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    /// `<f4`, the contract's type.
    F32,
    /// `<f8`, converted to f32 on read.
    F64,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }
}

/// What a header declares, once it is known to be one we accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArrayHeader {
    /// Element type.
    pub dtype: Dtype,
    /// Number of records (the first axis).
    pub records: u64,
}

/// Length of the fixed prefix before the dict for a given major version.
pub fn prefix_len(major: u8) -> Option<usize> {
    match major {
        1 => Some(10),
        2 | 3 => Some(12),
        _ => None,
    }
}

/// Parse the dict literal of a header and check it against the contract.
/// The error is the reason alone; the reader adds path, record and offset.
pub fn parse_dict(text: &str) -> Result<ArrayHeader, String> {
    let mut descr = None;
    let mut fortran = None;
    let mut shape = None;
    let mut p = Parser { s: text.trim_end().as_bytes(), i: 0 };
    p.expect(b'{')?;
    loop {
        p.ws();
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.ws();
        p.expect(b':')?;
        p.ws();
        match key.as_str() {
            "descr" => descr = Some(p.string()?),
            "fortran_order" => fortran = Some(p.boolean()?),
            "shape" => shape = Some(p.tuple()?),
            other => return Err(format!("unexpected header key {other:?}")),
        }
        p.ws();
        if !p.eat(b',') {
            p.ws();
            p.expect(b'}')?;
            break;
        }
    }
    let descr = descr.ok_or("header has no 'descr'")?;
    let fortran = fortran.ok_or("header has no 'fortran_order'")?;
    let shape = shape.ok_or("header has no 'shape'")?;
    let dtype = match descr.as_str() {
        "<f4" => Dtype::F32,
        "<f8" => Dtype::F64,
        other => return Err(format!("dtype {other:?} is not supported (expected '<f4', or '<f8' which is converted)")),
    };
    if fortran {
        return Err("Fortran-order array; write it in C order (numpy.ascontiguousarray)".into());
    }
    let expected = [ROWS as u64, COLS as u64, CHANNELS as u64];
    if shape.len() != 4 || shape[1..] != expected {
        let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
        return Err(format!("shape ({}) is not (N, 21, 5, 2)", dims.join(", ")));
    }
    Ok(ArrayHeader { dtype, records: shape[0] })
}

/// The complete header `numpy.save` writes for `records` DEMs as `<f4`:
/// always 128 bytes for any count below 10^21, so a writer can reserve it
/// and patch the count in place when the stream ends.
pub fn f32_header(records: u64) -> Vec<u8> {
    f32_array_header(&[records, ROWS as u64, COLS as u64, CHANNELS as u64])
}

/// A v1.0 header of a C-order `<f4` array of `shape` (not necessarily a
/// DEM array: see [`super::array`]). Its length depends on the dimensions
/// after the first only: it is padded for the longest first dimension (a
/// u64), at least to [`HEADER_LEN`], so a writer can reserve it and patch
/// the record count in place. For every count below 10^21 it is the header
/// `numpy.save` writes, byte for byte, when that is at most 128 bytes.
pub fn f32_array_header(shape: &[u64]) -> Vec<u8> {
    let dict = |first: u64| {
        let dims: Vec<String> = std::iter::once(first).chain(shape.iter().skip(1).copied()).map(|d| d.to_string()).collect();
        // numpy writes a 1-tuple with a trailing comma.
        let tuple = if dims.len() == 1 { format!("{},", dims[0]) } else { dims.join(", ") };
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({tuple}), }}")
    };
    let text = dict(shape.first().copied().unwrap_or(0));
    let longest = MAGIC.len() + 4 + dict(u64::MAX).len() + 1;
    let total = longest.next_multiple_of(64).max(HEADER_LEN);
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&((total - 10) as u16).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    out.resize(total - 1, b' ');
    out.push(b'\n');
    out
}

/// Size of the header [`f32_header`] writes.
pub const HEADER_LEN: usize = 128;

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
}

impl Parser<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }
    fn eat(&mut self, c: u8) -> bool {
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }
    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!("malformed header: expected '{}' at character {}", c as char, self.i))
        }
    }
    fn string(&mut self) -> Result<String, String> {
        let q = *self.s.get(self.i).ok_or("malformed header: ends early")?;
        if q != b'\'' && q != b'"' {
            return Err(format!("malformed header: expected a string at character {}", self.i));
        }
        self.i += 1;
        let start = self.i;
        while self.i < self.s.len() && self.s[self.i] != q {
            self.i += 1;
        }
        let out = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
        self.expect(q)?;
        Ok(out)
    }
    fn boolean(&mut self) -> Result<bool, String> {
        for (word, v) in [("True", true), ("False", false)] {
            if self.s[self.i..].starts_with(word.as_bytes()) {
                self.i += word.len();
                return Ok(v);
            }
        }
        Err(format!("malformed header: expected True or False at character {}", self.i))
    }
    fn tuple(&mut self) -> Result<Vec<u64>, String> {
        self.expect(b'(')?;
        let mut dims = Vec::new();
        loop {
            self.ws();
            if self.eat(b')') {
                return Ok(dims);
            }
            let start = self.i;
            while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                self.i += 1;
            }
            let digits = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
            dims.push(digits.parse().map_err(|_| format!("malformed header: expected a dimension at character {start}"))?);
            self.ws();
            if !self.eat(b',') {
                self.ws();
                self.expect(b')')?;
                return Ok(dims);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_what_numpy_writes() {
        let h = "{'descr': '<f4', 'fortran_order': False, 'shape': (7, 21, 5, 2), }";
        assert_eq!(parse_dict(h).unwrap(), ArrayHeader { dtype: Dtype::F32, records: 7 });
        let h = "{'descr': '<f8', 'fortran_order': False, 'shape': (0, 21, 5, 2)}";
        assert_eq!(parse_dict(h).unwrap().dtype, Dtype::F64);
    }

    #[test]
    fn refuses_other_dtypes_orders_and_shapes() {
        let bad = [
            ("{'descr': '<i4', 'fortran_order': False, 'shape': (1, 21, 5, 2), }", "dtype"),
            ("{'descr': '>f4', 'fortran_order': False, 'shape': (1, 21, 5, 2), }", "dtype"),
            ("{'descr': '<f4', 'fortran_order': True, 'shape': (1, 21, 5, 2), }", "Fortran"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (1, 20, 5, 2), }", "shape"),
            ("{'descr': '<f4', 'fortran_order': False, 'shape': (21, 5, 2), }", "shape"),
            ("{'descr': '<f4', 'fortran_order': False }", "shape"),
            ("{'descr': '<f4' 'shape'}", "malformed"),
        ];
        for (h, word) in bad {
            let e = parse_dict(h).unwrap_err();
            assert!(e.contains(word), "{h}: {e}");
        }
    }

    #[test]
    fn header_is_128_bytes_and_aligned() {
        for n in [0, 1, 12345, u64::MAX] {
            let h = f32_header(n);
            assert_eq!(h.len(), HEADER_LEN);
            assert_eq!(*h.last().unwrap(), b'\n');
            let dict = std::str::from_utf8(&h[10..]).unwrap();
            assert_eq!(parse_dict(dict).unwrap().records, n);
        }
    }
}
