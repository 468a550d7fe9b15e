#![no_main]
use voxcast::fuzz_support::{run, Target};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = run(Target::Zarr, data);
});
