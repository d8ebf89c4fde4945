//! Pipeline push with arbitrary intrinsics, depth settings, frame sizes and bytes.
#![no_main]

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::push_frame(data));
