//! What the container readers may hold, and reading within it.
//!
//! Every length a file declares (a record, a chunk, its decompressed size)
//! is checked against [`MAX_RECORD_BYTES`] and against the bytes left in
//! the file before anything is allocated, and a chunk is decompressed into
//! a buffer of exactly its declared size: a compressed chunk that holds
//! more is refused as soon as it gives one byte more. So a recording is
//! read in one buffer of at most [`MAX_RECORD_BYTES`], plus the
//! decompressor's state (a zstd window of at most 2^[`ZSTD_WINDOW_LOG_MAX`]
//! bytes, lz4 and bz2 blocks of at most 4 MB), whatever its headers say.

use std::io::{self, Read, Seek, SeekFrom};

/// The largest record or chunk (after decompression) a reader takes: 32 MiB,
/// 25 times the chunks `rosbag record` and rosbag2 write and room for one
/// map of 8 layers of 1,000 x 1,000 cells. A larger one is stepped over
/// with a warning that names this limit.
pub const MAX_RECORD_BYTES: u64 = 32 << 20;

/// The largest zstd window accepted (16 MiB; zstd's levels up to 19 use at
/// most 8 MiB): a frame that asks for more is refused, not allocated.
pub const ZSTD_WINDOW_LOG_MAX: u32 = 24;

/// `n` bytes in words: "33554432 bytes (32 MiB)".
pub fn bytes(n: u64) -> String {
    if n >= 1 << 20 && n.is_multiple_of(1 << 20) {
        format!("{n} bytes ({} MiB)", n >> 20)
    } else {
        format!("{n} bytes")
    }
}

/// Why `declared` bytes are not read: more than the limit.
pub fn over_limit(what: &str, declared: u64) -> String {
    format!("{what} of {declared} bytes is larger than the {} limit, stepped over", bytes(MAX_RECORD_BYTES))
}

/// Compressions a chunk may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Codec {
    /// bzip2 (ROS 1 bags).
    Bz2,
    /// An lz4 frame (ROS 1 bags, MCAP).
    Lz4,
    /// A zstd frame (MCAP).
    Zstd,
}

impl Codec {
    fn name(self) -> &'static str {
        match self {
            Codec::Bz2 => "bz2",
            Codec::Lz4 => "lz4",
            Codec::Zstd => "zstd",
        }
    }
}

/// Decompress `src` (a stream of `codec`) into `out`, which must be exactly
/// the size the chunk declares: fewer bytes or one byte more is an error, so
/// a small chunk that expands to gigabytes costs `out.len() + 1` bytes of
/// output, no more. `out.len()` must already be within [`MAX_RECORD_BYTES`].
pub fn decompress_exact(codec: Codec, src: impl Read, out: &mut [u8]) -> Result<(), String> {
    let what = codec.name();
    let err = |e: io::Error| format!("{what} chunk: {e}");
    match codec {
        Codec::Bz2 => fill_exact(bzip2::read::BzDecoder::new(src), out, what),
        Codec::Lz4 => fill_exact(lz4::Decoder::new(src).map_err(err)?, out, what),
        Codec::Zstd => {
            let mut d = zstd::stream::read::Decoder::new(src).map_err(err)?;
            d.window_log_max(ZSTD_WINDOW_LOG_MAX).map_err(err)?;
            fill_exact(d, out, what)
        }
    }
}

fn fill_exact(mut d: impl Read, out: &mut [u8], what: &str) -> Result<(), String> {
    let size = out.len();
    let mut got = 0;
    while got < size {
        match d.read(&mut out[got..]) {
            Ok(0) => return Err(format!("{what} chunk decompresses to {got} bytes, its header says {size}")),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(format!("{what} chunk: {e}")),
        }
    }
    let mut one = [0u8; 1];
    loop {
        match d.read(&mut one) {
            Ok(0) => return Ok(()),
            Ok(_) => return Err(format!("{what} chunk decompresses to more than the {size} bytes its header says")),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            // The declared bytes are all there; what follows them is not read.
            Err(_) => return Ok(()),
        }
    }
}

/// `buf` grown (never shrunk: it is reused record after record) to at least
/// `n` bytes, its first `n` returned. `n` must be within [`MAX_RECORD_BYTES`].
pub fn sized(buf: &mut Vec<u8>, n: usize) -> &mut [u8] {
    debug_assert!(n as u64 <= MAX_RECORD_BYTES);
    if buf.len() < n {
        buf.resize(n, 0);
    }
    &mut buf[..n]
}

/// Step over `n` bytes of `r`: read through a few, seek past many.
pub fn skip<R: Read + Seek>(r: &mut R, n: u64) -> io::Result<()> {
    if n == 0 {
        return Ok(());
    }
    if n <= 64 << 10 {
        let copied = io::copy(&mut Read::take(&mut *r, n), &mut io::sink())?;
        if copied < n {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        return Ok(());
    }
    let n = i64::try_from(n).map_err(|_| io::Error::from(io::ErrorKind::InvalidInput))?;
    r.seek(SeekFrom::Current(n)).map(|_| ())
}

/// Read exactly `buf.len()` bytes; Ok(false) at a clean end of file before
/// the first byte.
pub fn read_or_end(r: &mut impl Read, buf: &mut [u8]) -> io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chunk_that_expands_past_its_declared_size_is_refused_after_one_byte_more() {
        let zeros = vec![0u8; 10 << 20];
        let z = zstd::bulk::compress(&zeros, 3).unwrap();
        let mut out = vec![0u8; 1000];
        let e = decompress_exact(Codec::Zstd, &z[..], &mut out).unwrap_err();
        assert!(e.contains("more than the 1000 bytes"), "{e}");
        let mut all = vec![0u8; 10 << 20];
        decompress_exact(Codec::Zstd, &z[..], &mut all).unwrap();
        let mut more = vec![0u8; (10 << 20) + 1];
        assert!(decompress_exact(Codec::Zstd, &z[..], &mut more).unwrap_err().contains("decompresses to 10485760 bytes"));
        assert!(decompress_exact(Codec::Lz4, &b"garbage garbage"[..], &mut out).is_err());
        assert!(decompress_exact(Codec::Bz2, &b"BZh9garbage"[..], &mut out).is_err());
        assert!(decompress_exact(Codec::Zstd, &b"\x28\xb5\x2f\xfdgarbage"[..], &mut out).is_err());
    }
}
