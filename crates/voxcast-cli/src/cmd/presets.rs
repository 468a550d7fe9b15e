//! `voxcast presets`.

pub fn run() {
    println!("Transfer-function presets (--tf NAME):");
    println!(
        "  {:<16} chosen from the data's histogram (the default)",
        "auto"
    );
    for (n, d) in voxcast::transfer::PRESETS {
        println!("  {n:<16} {d}");
    }
    println!("\nBuilt-in volumes (INPUT = builtin:NAME):");
    for (n, d) in voxcast::builtin::BUILTINS {
        println!("  {n:<16} {d}");
    }
}
