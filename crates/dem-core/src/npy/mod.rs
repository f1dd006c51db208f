//! NPY streams as the contract defines them: read one or many concatenated
//! `.npy` arrays, write a numpy-loadable array or a stream of them; and
//! [`array`](mod@array), a plain `<f4` array writer of any record shape for side
//! outputs outside the contract (NaN allowed).

pub mod array;
pub mod header;
pub mod index;
pub mod reader;
pub mod transform;
pub mod writer;

pub use array::F32ArrayWriter;
pub use index::{ByIndex, RecordIndex};
pub use reader::{estimate_records, open, read_all, read_selected, ArrayExtent, NpyReader, CHUNK_RECORDS};
pub use transform::{transform, transform_checked};
pub use writer::{create, write_all, NpyWriter};

/// Pipe capacity asked for on a stdin or stdout that is a pipe: 1 MiB, the
/// most an unprivileged process may ask (`/proc/sys/fs/pipe-max-size`).
/// With the default 64 KiB, two stream tools in a pipeline wake each other
/// for every 64 KiB, which costs more than the copying (twice the time of
/// `numpy.load` + `numpy.save` on a virtual machine).
pub const PIPE_BYTES: usize = 1 << 20;

/// Best effort: grow the pipe behind `fd` to [`PIPE_BYTES`]. Not a pipe, an
/// older kernel or the per-user pipe quota spent: nothing changes.
pub(crate) fn grow_pipe(fd: impl std::os::fd::AsFd) {
    #[cfg(target_os = "linux")]
    let _ = rustix::pipe::fcntl_setpipe_size(fd, PIPE_BYTES);
    #[cfg(not(target_os = "linux"))]
    let _ = fd;
}
