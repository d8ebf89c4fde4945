//! Frame decoding from arbitrary bytes (colour + depth images).
#![no_main]

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::decode_frame(data));
