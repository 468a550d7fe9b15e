//! Sets `cfg(packets)` where the SIMD ray packets are compiled: x86-64
//! (AVX2 + FMA and AVX-512, picked at run time) and AArch64 (NEON). Any
//! other target, or `VOXCAST_NO_PACKETS=1` at build time (which CI uses to
//! build and test that configuration on x86-64), renders with the scalar
//! loop alone.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(packets)");
    println!("cargo::rerun-if-env-changed=VOXCAST_NO_PACKETS");
    println!("cargo::rerun-if-changed=build.rs");
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let off = std::env::var("VOXCAST_NO_PACKETS").is_ok_and(|v| !v.is_empty() && v != "0");
    if !off && (arch == "x86_64" || arch == "aarch64") {
        println!("cargo::rustc-cfg=packets");
    }
}
