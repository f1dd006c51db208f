//! NPY streams as the contract defines them: read one or many concatenated
//! `.npy` arrays, write a numpy-loadable array or a stream of them.

pub mod header;
pub mod reader;
pub mod writer;

pub use reader::{open, read_all, NpyReader, CHUNK_RECORDS};
pub use writer::{create, write_all, NpyWriter};
