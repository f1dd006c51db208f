//! PNG pictures of DEMs.
