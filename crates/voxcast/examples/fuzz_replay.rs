//! Runs inputs through a fuzz target's entry point (`voxcast::fuzz_support`)
//! and prints what each reader call gave: to reproduce a fuzzer finding
//! without the nightly toolchain, or to check that seeds reach the readers.
//!
//! `cargo run -p voxcast --example fuzz_replay -- TARGET FILE...`

use voxcast::fuzz_support::{run, Target};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(target) = args.first().and_then(|n| Target::from_name(n)) else {
        let names: Vec<&str> = Target::ALL.iter().map(|t| t.name()).collect();
        eprintln!(
            "usage: fuzz_replay TARGET FILE...  (targets: {})",
            names.join(" ")
        );
        std::process::exit(2);
    };
    for f in &args[1..] {
        let bytes = std::fs::read(f).unwrap_or_else(|e| panic!("cannot read {f}: {e}"));
        println!("{f}:");
        for o in run(target, &bytes) {
            match o {
                Ok(s) => println!("  ok: {}", s.lines().next().unwrap_or("")),
                Err(e) => println!("  err: {e}"),
            }
        }
    }
}
