#![no_main]
use voxcast::fuzz_support::{run, Target};

libfuzzer_sys::fuzz_target!(
    init: {
        // The TIFF decoder runs under io::util::no_panic (the `tiff` crate
        // panics on some malformed files); libFuzzer's hook would abort on
        // those before they are caught. A panic that escapes `run` still
        // aborts.
        let _ = std::panic::take_hook();
    },
    |data: &[u8]| {
        let _ = run(Target::ImageStack, data);
    }
);
