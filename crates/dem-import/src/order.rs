//! Stamp order in bounded memory, whatever the recording's length.
//!
//! DEMs come out of a recording in file order, which is nearly (not quite)
//! stamp order; the outputs are written in stamp order. [`StampOrder`]
//! holds up to `cap` records in memory: a recording with fewer is sorted
//! there, as a whole. Past that, each full buffer is sorted and spilled as a
//! run to an unnamed temp file in the output folder (gone when the process
//! ends, also after a kill), and the runs are merged at the end. Runs are
//! merged as they pile up, `fan_in` of one level into one of the next (each
//! record is copied about log_fan_in(records / cap) times), so at most
//! `fan_in - 1` runs per level are open. Memory: `cap` records plus a small
//! read-ahead per run; disk: a record's bytes per DEM, a few times over
//! during a merge.
//!
//! The order is exactly a stable sort by stamp: records with the same stamp
//! come out in the order they went in (runs are merged oldest first on
//! ties), so the outputs are the bytes an in-memory sort gives.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};
use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use dem_core::format::{Dem, RECORD_LEN};

/// A record with a stamp and a fixed-size byte form for the spilled runs.
pub trait Record: Sized {
    /// Bytes of one record in a run.
    const BYTES: usize;
    /// The key of the order (ns).
    fn stamp(&self) -> i64;
    /// Append the record's bytes to `out`.
    fn put(&self, out: &mut Vec<u8>);
    /// The record from its `BYTES` bytes.
    fn get(b: &[u8]) -> Self;
}

/// One DEM with what its label needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The map's header stamp (ns).
    pub stamp: i64,
    /// The DEM.
    pub dem: Dem,
    /// The robot's x in the map's frame (m).
    pub x: f64,
    /// The robot's y in the map's frame (m).
    pub y: f64,
    /// The robot's heading (rad).
    pub yaw: f64,
}

impl Record for Imported {
    const BYTES: usize = 8 + 4 * RECORD_LEN + 3 * 8;

    fn stamp(&self) -> i64 {
        self.stamp
    }

    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.stamp.to_le_bytes());
        for v in &self.dem {
            out.extend_from_slice(&v.to_bits().to_le_bytes());
        }
        for v in [self.x, self.y, self.yaw] {
            out.extend_from_slice(&v.to_bits().to_le_bytes());
        }
    }

    fn get(b: &[u8]) -> Self {
        let u64_at = |at: usize| u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"));
        let mut dem = [0f32; RECORD_LEN];
        for (k, v) in dem.iter_mut().enumerate() {
            let at = 8 + 4 * k;
            *v = f32::from_bits(u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes")));
        }
        let f = 8 + 4 * RECORD_LEN;
        Imported {
            stamp: u64_at(0) as i64,
            dem,
            x: f64::from_bits(u64_at(f)),
            y: f64::from_bits(u64_at(f + 8)),
            yaw: f64::from_bits(u64_at(f + 16)),
        }
    }
}

/// Records held in memory before a run is spilled (about 3.6 MB of DEMs).
pub const CAP: usize = 4096;
/// Runs merged at a time.
pub const FAN_IN: usize = 64;
/// Records read ahead per run while merging.
const READ_AHEAD: usize = 32;

/// Where a run's records go as it is written.
type Sink<'a, T> = dyn FnMut(&T) -> io::Result<()> + 'a;

/// A sorted run: `len` records at byte `offset` of `file`; `level` is the
/// number of merges that made it.
struct Run {
    file: Rc<File>,
    offset: u64,
    len: u64,
    level: u32,
}

/// Records in, records out in stamp order; see the module's notes.
pub struct StampOrder<T: Record> {
    dir: PathBuf,
    cap: usize,
    fan_in: usize,
    held: Vec<T>,
    runs: Vec<Run>,
    /// The file runs are being appended to, and its end.
    current: Option<(Rc<File>, u64)>,
    /// The first error spilling met; reported by [`StampOrder::finish`].
    failed: Option<io::Error>,
    spilled: u64,
}

fn read_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0;
        while done < buf.len() {
            match std::os::windows::fs::FileExt::seek_read(file, &mut buf[done..], offset + done as u64)? {
                0 => return Err(io::ErrorKind::UnexpectedEof.into()),
                n => done += n,
            }
        }
        Ok(())
    }
}

fn write_at(file: &File, buf: &[u8], offset: u64) -> io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::write_all_at(file, buf, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0;
        while done < buf.len() {
            match std::os::windows::fs::FileExt::seek_write(file, &buf[done..], offset + done as u64)? {
                0 => return Err(io::ErrorKind::WriteZero.into()),
                n => done += n,
            }
        }
        Ok(())
    }
}

/// A run read back a few records at a time.
struct RunReader<T> {
    run: Run,
    next: u64,
    ahead: VecDeque<T>,
    buf: Vec<u8>,
}

impl<T: Record> RunReader<T> {
    fn new(run: Run) -> Self {
        RunReader { run, next: 0, ahead: VecDeque::new(), buf: Vec::new() }
    }

    fn pop(&mut self) -> io::Result<Option<T>> {
        if self.ahead.is_empty() && self.next < self.run.len {
            let n = (self.run.len - self.next).min(READ_AHEAD as u64);
            self.buf.resize(n as usize * T::BYTES, 0);
            read_at(&self.run.file, &mut self.buf, self.run.offset + self.next * T::BYTES as u64)?;
            self.ahead.extend(self.buf.chunks_exact(T::BYTES).map(T::get));
            self.next += n;
        }
        Ok(self.ahead.pop_front())
    }
}

/// Merge `runs` (oldest first), then the sorted `tail`, calling `out` with
/// each record in stamp order; ties go to the older source.
fn merge<T: Record>(runs: Vec<Run>, tail: Vec<T>, out: &mut dyn FnMut(T) -> io::Result<()>) -> io::Result<()> {
    let mut readers: Vec<RunReader<T>> = runs.into_iter().map(RunReader::new).collect();
    let mut tail = tail.into_iter();
    let t = readers.len();
    let mut heads: Vec<Option<T>> = Vec::with_capacity(t + 1);
    for r in &mut readers {
        heads.push(r.pop()?);
    }
    heads.push(tail.next());
    let mut heap: BinaryHeap<Reverse<(i64, usize)>> =
        heads.iter().enumerate().filter_map(|(k, h)| h.as_ref().map(|h| Reverse((h.stamp(), k)))).collect();
    while let Some(Reverse((_, k))) = heap.pop() {
        let rec = heads[k].take().expect("a head for each heap entry");
        heads[k] = if k < t { readers[k].pop()? } else { tail.next() };
        if let Some(h) = &heads[k] {
            heap.push(Reverse((h.stamp(), k)));
        }
        out(rec)?;
    }
    Ok(())
}

impl<T: Record> StampOrder<T> {
    /// A sorter spilling into `dir` (the output folder) past [`CAP`] records.
    pub fn new(dir: &Path) -> Self {
        Self::with_limits(dir, CAP, FAN_IN)
    }

    /// A sorter holding `cap` records and merging `fan_in` runs at a time.
    pub fn with_limits(dir: &Path, cap: usize, fan_in: usize) -> Self {
        StampOrder {
            dir: dir.to_path_buf(),
            cap: cap.max(1),
            fan_in: fan_in.max(2),
            held: Vec::new(),
            runs: Vec::new(),
            current: None,
            failed: None,
            spilled: 0,
        }
    }

    /// Records held in memory now.
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// Sorted runs on disk now.
    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    /// Records spilled to disk so far (merges count again).
    pub fn spilled(&self) -> u64 {
        self.spilled
    }

    /// Add one record. An error spilling is kept for [`StampOrder::finish`];
    /// the records after it are dropped.
    pub fn push(&mut self, rec: T) {
        if self.failed.is_some() {
            return;
        }
        self.held.push(rec);
        if self.held.len() >= self.cap {
            if let Err(e) = self.spill() {
                self.failed = Some(e);
                self.held = Vec::new();
                self.runs.clear();
            }
        }
    }

    /// Append `n` records from `fill` (which hands each to the sink it is
    /// given, in order) as one run of the current file.
    fn append_run(&mut self, n: u64, level: u32, fill: &mut dyn FnMut(&mut Sink<'_, T>) -> io::Result<()>) -> io::Result<Run> {
        let (file, start) = match self.current.take() {
            Some(c) => c,
            None => (Rc::new(tempfile::tempfile_in(&self.dir)?), 0),
        };
        let mut end = start;
        let mut buf = Vec::with_capacity(64 * T::BYTES);
        fill(&mut |rec: &T| {
            rec.put(&mut buf);
            if buf.len() >= 64 * T::BYTES {
                write_at(&file, &buf, end)?;
                end += buf.len() as u64;
                buf.clear();
            }
            Ok(())
        })?;
        write_at(&file, &buf, end)?;
        end += buf.len() as u64;
        debug_assert_eq!(end - start, n * T::BYTES as u64);
        self.spilled += n;
        self.current = Some((file.clone(), end));
        Ok(Run { file, offset: start, len: n, level })
    }

    fn spill(&mut self) -> io::Result<()> {
        let mut held = std::mem::take(&mut self.held);
        held.sort_by_key(|r| r.stamp());
        let n = held.len() as u64;
        let run = self.append_run(n, 0, &mut |put| held.iter().try_for_each(&mut *put))?;
        self.runs.push(run);
        // The newest fan_in runs of one level become one of the next, in
        // their place: they are the newest records, so ties keep their order.
        while self.runs.len() >= self.fan_in {
            let tail = &self.runs[self.runs.len() - self.fan_in..];
            let level = tail[0].level;
            if tail.iter().any(|r| r.level != level) {
                break;
            }
            let runs = self.runs.split_off(self.runs.len() - self.fan_in);
            let total: u64 = runs.iter().map(|r| r.len).sum();
            // A merged run gets a file of its own; the files of the runs it
            // replaces are freed with them.
            self.current = None;
            let run = self.append_run(total, level + 1, &mut |put| merge(runs_copy(&runs), Vec::new(), &mut |rec| put(&rec)))?;
            self.current = None;
            drop(runs);
            self.runs.push(run);
        }
        Ok(())
    }

    /// Every record in stamp order, to `out`. The error is a spill's or
    /// `out`'s.
    pub fn finish(mut self, out: &mut dyn FnMut(T) -> io::Result<()>) -> io::Result<()> {
        if let Some(e) = self.failed.take() {
            return Err(e);
        }
        let mut held = std::mem::take(&mut self.held);
        held.sort_by_key(|r| r.stamp());
        merge(std::mem::take(&mut self.runs), held, out)
    }
}

/// Copies of the runs' handles (the files stay open while the copies live).
fn runs_copy(runs: &[Run]) -> Vec<Run> {
    runs.iter().map(|r| Run { file: r.file.clone(), offset: r.offset, len: r.len, level: r.level }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (stamp, arrival): arrival shows the order of ties.
    #[derive(Clone, Copy, Debug, PartialEq)]
    struct Rec(i64, u64);

    impl Record for Rec {
        const BYTES: usize = 16;
        fn stamp(&self) -> i64 {
            self.0
        }
        fn put(&self, out: &mut Vec<u8>) {
            out.extend_from_slice(&self.0.to_le_bytes());
            out.extend_from_slice(&self.1.to_le_bytes());
        }
        fn get(b: &[u8]) -> Self {
            Rec(i64::from_le_bytes(b[..8].try_into().unwrap()), u64::from_le_bytes(b[8..16].try_into().unwrap()))
        }
    }

    /// A nearly sorted stream with ties, a few very late records and one
    /// that is earlier than all.
    fn recording(n: u64) -> Vec<Rec> {
        let mut s = 12345u64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut out: Vec<Rec> = (0..n)
            .map(|k| {
                let jitter = (rnd() % 7) as i64 - 3;
                let late = if rnd() % 97 == 0 { -500 } else { 0 };
                Rec((k as i64 / 3) * 10 + jitter + late, k)
            })
            .collect();
        out.push(Rec(-1_000_000, n));
        out
    }

    fn sorted(cap: usize, fan_in: usize, input: &[Rec]) -> (Vec<Rec>, usize, u64) {
        let dir = tempfile::tempdir().unwrap();
        let mut s = StampOrder::with_limits(dir.path(), cap, fan_in);
        let mut most = 0;
        for r in input {
            s.push(*r);
            most = most.max(s.held());
            assert!(s.runs() < fan_in * 8, "cap {cap}, fan-in {fan_in}: {} runs", s.runs());
        }
        let spilled = s.spilled();
        let mut out = Vec::new();
        s.finish(&mut |r| {
            out.push(r);
            Ok(())
        })
        .unwrap();
        (out, most, spilled)
    }

    #[test]
    fn any_length_comes_out_as_a_stable_sort_holding_at_most_cap_records() {
        let input = recording(5000);
        let mut want = input.clone();
        want.sort_by_key(|r| r.0);
        // In memory, one run level, and runs merged in several levels.
        for (cap, fan_in) in [(10_000, 64), (100, 64), (7, 4), (1, 2)] {
            let (got, most, spilled) = sorted(cap, fan_in, &input);
            assert!(got == want, "cap {cap}, fan-in {fan_in}: not a stable sort by stamp");
            assert!(most <= cap, "cap {cap}: held {most}");
            assert_eq!(spilled == 0, cap > input.len(), "cap {cap}: spilled {spilled}");
        }
        // Nothing in, nothing out.
        assert!(sorted(4, 2, &[]).0.is_empty());
    }

    #[test]
    fn imported_records_round_trip_bit_exactly() {
        let mut dem = [0f32; RECORD_LEN];
        for (k, v) in dem.iter_mut().enumerate() {
            *v = if k % 5 == 0 { f32::NAN } else { k as f32 * -0.37 };
        }
        let a = Imported { stamp: -7, dem, x: 1.0 / 3.0, y: -0.0, yaw: f64::MIN_POSITIVE };
        let mut b = Vec::new();
        a.put(&mut b);
        assert_eq!(b.len(), Imported::BYTES);
        let back = Imported::get(&b);
        assert_eq!(back.stamp, a.stamp);
        assert!(back.dem.iter().zip(&a.dem).all(|(p, q)| p.to_bits() == q.to_bits()));
        assert_eq!([back.x.to_bits(), back.y.to_bits(), back.yaw.to_bits()], [a.x.to_bits(), a.y.to_bits(), a.yaw.to_bits()]);
    }
}
