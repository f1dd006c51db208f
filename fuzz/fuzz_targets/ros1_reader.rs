//! Any bytes as a ROS 1 bag: messages and skipped parts handed out, then
//! the end or an error, never a panic; every message decoded as its type
//! says. Memory stays bounded by the reader's limits (libFuzzer's
//! -rss_limit_mb and -malloc_limit_mb catch an allocation by a declared size).
#![no_main]
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    common::read(data, common::Kind::Ros1);
});
