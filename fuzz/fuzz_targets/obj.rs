#![no_main]
use voxcast::fuzz_support::{run, Target};

libfuzzer_sys::fuzz_target!(
    init: {
        // The OBJ loader catches panics of the `tobj` parser by design
        // (geometry/obj.rs); libFuzzer's hook would abort on those before
        // they are caught. With the default hook a panic that escapes
        // `run` still aborts (libfuzzer-sys catches it and aborts).
        let _ = std::panic::take_hook();
    },
    |data: &[u8]| {
        let _ = run(Target::Obj, data);
    }
);
