//! The two serializations ROS messages arrive in, read in place.
//!
//! - **ROS 1**: little-endian, packed (no alignment); a string is a `u32`
//!   length and its bytes; a variable array a `u32` count and its elements.
//! - **CDR** (ROS 2, XCDR1 as rmw writes it): a 4-byte encapsulation header
//!   (`00 01` little-endian, `00 00` big-endian, two option bytes), then
//!   every primitive aligned to its size (at most 8) counted from the end of
//!   that header; a string is a `u32` length that counts a trailing NUL.
//!
//! A cursor never copies a float array: it returns where the array is, so a
//! 200 x 200 map layer costs its 400 looked-up cells, not 160 KB.

use std::fmt;

/// Which serialization a message uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// ROS 1 (`.bag` files, MCAP channels with encoding `ros1`).
    Ros1,
    /// CDR (MCAP channels with encoding `cdr`).
    Cdr,
}

/// A message that ends early or holds impossible sizes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WireError(pub String);

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Result of a decoding step.
pub type Result<T> = std::result::Result<T, WireError>;

/// Where an array of `f32` or `f64` lies in a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArrayAt {
    /// Byte offset of element 0 in the message buffer.
    pub offset: usize,
    /// Elements.
    pub len: usize,
    /// Big-endian elements (CDR_BE only).
    pub big_endian: bool,
}

impl ArrayAt {
    /// Element `k` of an `f32` array in `buf`.
    #[inline]
    pub fn f32(&self, buf: &[u8], k: usize) -> f32 {
        let at = self.offset + 4 * k;
        let b: [u8; 4] = buf[at..at + 4].try_into().expect("4 bytes");
        if self.big_endian {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        }
    }
}

/// A reading position in one serialized message.
pub struct Wire<'a> {
    buf: &'a [u8],
    pos: usize,
    /// Alignment origin (CDR: after the encapsulation header).
    origin: usize,
    cdr: bool,
    big_endian: bool,
}

impl<'a> Wire<'a> {
    /// Start reading `buf` in `encoding` (a CDR buffer starts with its
    /// encapsulation header, which is checked here).
    pub fn new(buf: &'a [u8], encoding: Encoding) -> Result<Self> {
        match encoding {
            Encoding::Ros1 => Ok(Wire { buf, pos: 0, origin: 0, cdr: false, big_endian: false }),
            Encoding::Cdr => {
                if buf.len() < 4 {
                    return Err(WireError(format!("{} bytes, shorter than a CDR header", buf.len())));
                }
                let big_endian = match (buf[0], buf[1]) {
                    (0, 1) => false,
                    (0, 0) => true,
                    (a, b) => return Err(WireError(format!("CDR encapsulation {a:#04x} {b:#04x} is not plain CDR"))),
                };
                Ok(Wire { buf, pos: 4, origin: 4, cdr: true, big_endian })
            }
        }
    }

    /// The whole message buffer.
    pub fn buf(&self) -> &'a [u8] {
        self.buf
    }

    fn align(&mut self, n: usize) {
        if self.cdr {
            let rel = self.pos - self.origin;
            self.pos += (n - rel % n) % n;
        }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end =
            self.pos.checked_add(n).filter(|&e| e <= self.buf.len()).ok_or_else(|| {
                WireError(format!("message ends at byte {} inside {what} (needs {n} bytes at {})", self.buf.len(), self.pos))
            })?;
        let s = &self.buf[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn fixed<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        self.align(N);
        Ok(self.take(N, what)?.try_into().expect("N bytes"))
    }

    /// A `uint16`.
    pub fn u16(&mut self, what: &str) -> Result<u16> {
        let b = self.fixed::<2>(what)?;
        Ok(if self.big_endian { u16::from_be_bytes(b) } else { u16::from_le_bytes(b) })
    }

    /// A `uint32`.
    pub fn u32(&mut self, what: &str) -> Result<u32> {
        let b = self.fixed::<4>(what)?;
        Ok(if self.big_endian { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) })
    }

    /// An `int32`.
    pub fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(self.u32(what)? as i32)
    }

    /// A `float64`.
    pub fn f64(&mut self, what: &str) -> Result<f64> {
        let b = self.fixed::<8>(what)?;
        Ok(if self.big_endian { f64::from_be_bytes(b) } else { f64::from_le_bytes(b) })
    }

    /// A count of a variable array, checked against the bytes left (each
    /// element takes at least `min_size` bytes), so a damaged count cannot
    /// make the reader allocate or loop beyond the message.
    pub fn count(&mut self, min_size: usize, what: &str) -> Result<usize> {
        let n = self.u32(what)? as usize;
        let left = self.buf.len() - self.pos;
        if n.saturating_mul(min_size.max(1)) > left {
            return Err(WireError(format!("{what}: {n} elements cannot fit in the {left} bytes left")));
        }
        Ok(n)
    }

    /// A `string` (UTF-8 checked).
    pub fn string(&mut self, what: &str) -> Result<&'a str> {
        let n = self.count(1, what)?;
        let bytes = self.take(n, what)?;
        let text = if self.cdr {
            // The length counts the terminating NUL.
            bytes.strip_suffix(&[0]).ok_or_else(|| WireError(format!("{what}: CDR string without its NUL")))?
        } else {
            bytes
        };
        std::str::from_utf8(text).map_err(|_| WireError(format!("{what}: not UTF-8")))
    }

    /// A `string[]`.
    pub fn strings(&mut self, what: &str) -> Result<Vec<&'a str>> {
        let n = self.count(4, what)?;
        (0..n).map(|_| self.string(what)).collect()
    }

    /// A `float32[]`, located, not copied.
    pub fn f32_array(&mut self, what: &str) -> Result<ArrayAt> {
        let n = self.count(4, what)?;
        self.align(4);
        let offset = self.pos;
        self.take(4 * n, what)?;
        Ok(ArrayAt { offset, len: n, big_endian: self.big_endian })
    }

    /// A `float64[]`, copied (joint positions: a handful).
    pub fn f64_array(&mut self, what: &str) -> Result<Vec<f64>> {
        let n = self.count(8, what)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// A time (`time` in ROS 1: u32 s + u32 ns; `builtin_interfaces/Time`
    /// in ROS 2: i32 s + u32 ns) as nanoseconds.
    pub fn time(&mut self, what: &str) -> Result<i64> {
        let sec = if self.cdr { self.i32(what)? as i64 } else { self.u32(what)? as i64 };
        let nsec = self.u32(what)? as i64;
        Ok(sec * 1_000_000_000 + nsec)
    }

    /// A `std_msgs/Header`: (stamp in ns, frame_id). ROS 1's has a `seq` first.
    pub fn header(&mut self) -> Result<(i64, &'a str)> {
        if !self.cdr {
            self.u32("header.seq")?;
        }
        let stamp = self.time("header.stamp")?;
        let frame = self.string("header.frame_id")?;
        Ok((stamp, frame))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_from_after_the_encapsulation_header() {
        // header, u16 7, (pad 2), u32 9, (pad 0), f64 1.5, string "ab"
        let mut b = vec![0, 1, 0, 0];
        b.extend(7u16.to_le_bytes());
        b.extend([0, 0]);
        b.extend(9u32.to_le_bytes());
        b.extend(1.5f64.to_le_bytes());
        b.extend(3u32.to_le_bytes());
        b.extend(b"ab\0");
        let mut w = Wire::new(&b, Encoding::Cdr).unwrap();
        assert_eq!(w.u16("a").unwrap(), 7);
        assert_eq!(w.u32("b").unwrap(), 9);
        assert_eq!(w.f64("c").unwrap(), 1.5);
        assert_eq!(w.string("d").unwrap(), "ab");
    }

    #[test]
    fn ros1_is_packed_and_big_endian_cdr_reads() {
        let mut b = vec![];
        b.extend(7u16.to_le_bytes());
        b.extend(1.5f64.to_le_bytes());
        b.extend(2u32.to_le_bytes());
        b.extend(b"ab");
        let mut w = Wire::new(&b, Encoding::Ros1).unwrap();
        assert_eq!((w.u16("a").unwrap(), w.f64("b").unwrap(), w.string("c").unwrap()), (7, 1.5, "ab"));

        let mut be = vec![0, 0, 0, 0];
        be.extend(2u32.to_be_bytes());
        be.extend(0.5f32.to_be_bytes());
        be.extend((-2.0f32).to_be_bytes());
        let mut w = Wire::new(&be, Encoding::Cdr).unwrap();
        let a = w.f32_array("x").unwrap();
        assert_eq!((a.f32(&be, 0), a.f32(&be, 1)), (0.5, -2.0));
    }

    #[test]
    fn damaged_counts_and_short_messages_are_refused_not_followed() {
        let mut b = vec![];
        b.extend(u32::MAX.to_le_bytes());
        assert!(Wire::new(&b, Encoding::Ros1).unwrap().f32_array("data").unwrap_err().0.contains("cannot fit"));
        let e = Wire::new(&[1, 2], Encoding::Ros1).unwrap().u32("seq").unwrap_err();
        assert!(e.0.contains("ends at byte 2 inside seq"), "{e}");
        assert!(Wire::new(&[1, 2, 0, 0], Encoding::Cdr).is_err());
    }
}
