//! Which packet build runs on this CPU ([`level`]): on x86-64 sixteen
//! lanes in AVX-512 registers or two packets of eight in AVX2 ones, each
//! fetching by the gather instructions or by scalar loads, whichever this
//! CPU runs faster ([`loads_beat_gathers`]); on AArch64 four packets of
//! four in NEON registers.

/// The instruction set a packet is compiled for, picked at run time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// AVX2 + FMA: eight lanes in 256-bit registers (a packet's sixteen
    /// rays as two packets of eight), fetching by the AVX2 gathers.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// The same, fetching lane by lane with scalar loads: faster where the
    /// gathers are slow (AMD's cores, Intel's from Skylake to Ice Lake:
    /// `dispatch::loads_beat_gathers`).
    #[cfg(target_arch = "x86_64")]
    #[serde(rename = "avx2-loads")]
    Avx2Loads,
    /// AVX-512 F: sixteen lanes in 512-bit registers, lane masks in mask
    /// registers, thirty-two registers.
    #[cfg(target_arch = "x86_64")]
    Avx512,
    /// The same, fetching lane by lane with scalar loads: faster where the
    /// AVX-512 gathers are slow (AMD's Zen 5, Intel's Skylake-SP to Ice
    /// Lake: `dispatch::loads_beat_gathers`).
    #[cfg(target_arch = "x86_64")]
    #[serde(rename = "avx512-loads")]
    Avx512Loads,
    /// AArch64's NEON: four lanes in 128-bit registers (a packet's
    /// sixteen rays as four packets of four), fetching lane by lane with
    /// scalar loads (NEON has no gather).
    #[cfg(target_arch = "aarch64")]
    Neon,
}

impl Level {
    pub fn name(self) -> &'static str {
        match self {
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => "avx2",
            #[cfg(target_arch = "x86_64")]
            Level::Avx2Loads => "avx2-loads",
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => "avx512",
            #[cfg(target_arch = "x86_64")]
            Level::Avx512Loads => "avx512-loads",
            #[cfg(target_arch = "aarch64")]
            Level::Neon => "neon",
        }
    }
}

/// The packets' level on this CPU under `simd`, or `None` where the scalar
/// loop runs (x86-64 without AVX2 + FMA, a target other than x86-64 and
/// AArch64, or `Simd::Scalar`). On AArch64 `Simd::Auto` picks NEON, and
/// the x86 levels are the scalar loop, as AVX-512 is on a CPU without it.
pub fn level(simd: crate::render::Simd) -> Option<Level> {
    #[cfg(all(packets, target_arch = "x86_64"))]
    {
        use crate::render::Simd;
        let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
        let avx512 = std::is_x86_feature_detected!("avx512f");
        match simd {
            Simd::Scalar => None,
            _ if !avx2 => None,
            Simd::Auto if avx512 && gathers_by_loads() => Some(Level::Avx512Loads),
            Simd::Auto if avx512 => Some(Level::Avx512),
            Simd::Auto if gathers_by_loads() => Some(Level::Avx2Loads),
            Simd::Auto | Simd::Avx2 => Some(Level::Avx2),
            Simd::Avx2Loads => Some(Level::Avx2Loads),
            Simd::Avx512 | Simd::Avx512Loads if !avx512 => None,
            Simd::Avx512 => Some(Level::Avx512),
            Simd::Avx512Loads => Some(Level::Avx512Loads),
        }
    }
    #[cfg(all(packets, target_arch = "aarch64"))]
    {
        match simd {
            crate::render::Simd::Auto => Some(Level::Neon),
            _ => None,
        }
    }
    #[cfg(not(packets))]
    {
        let _ = simd;
        None
    }
}

/// Whether the packets fetch by scalar loads rather than the gather
/// instructions on this CPU ([`loads_beat_gathers`] of its CPUID vendor,
/// family and model).
#[cfg(all(packets, target_arch = "x86_64"))]
fn gathers_by_loads() -> bool {
    // CPUID once per process: `level` runs for every render (in a virtual
    // machine each CPUID is a trap to the hypervisor).
    static LOADS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *LOADS.get_or_init(cpuid_loads)
}

/// [`gathers_by_loads`] from CPUID.
#[cfg(all(packets, target_arch = "x86_64"))]
fn cpuid_loads() -> bool {
    use std::arch::x86_64::__cpuid;
    // SAFETY: CPUID leaves 0 and 1 exist on every x86-64 CPU.
    #[allow(unused_unsafe)]
    let (r0, r1) = unsafe { (__cpuid(0), __cpuid(1)) };
    let mut v = [0u8; 12];
    v[..4].copy_from_slice(&r0.ebx.to_le_bytes());
    v[4..8].copy_from_slice(&r0.edx.to_le_bytes());
    v[8..].copy_from_slice(&r0.ecx.to_le_bytes());
    // The displayed family and model (Intel SDM, CPUID leaf 1).
    let base_family = (r1.eax >> 8) & 0xf;
    let family = base_family
        + if base_family == 0xf {
            (r1.eax >> 20) & 0xff
        } else {
            0
        };
    let mut model = (r1.eax >> 4) & 0xf;
    if base_family == 0x6 || base_family == 0xf {
        model |= ((r1.eax >> 16) & 0xf) << 4;
    }
    loads_beat_gathers(&v, family, model)
}

/// Whether a CPU of this vendor, family and model fetches the packets'
/// voxels and table rows faster by scalar loads than by gathers:
///
/// * AMD's cores (and Hygon's, the same design): their gathers are slower
///   than the loads. Measured on an AMD EPYC (Zen 3, AVX2), the same
///   frames, alternating builds: Marschner–Lobb 256³ unshaded 156–162 →
///   125–131 ms, the teapot 57–64 → 53–60 ms; on an AMD EPYC (Zen 5,
///   AVX-512), one thread: 131–136 → 92–95 ms and 49–51 → 39–41 ms
///   (docs/engine.md, "Gathers or loads").
/// * Intel's cores from Skylake to Ice Lake, Tiger Lake and Rocket Lake:
///   the generations whose gathers Intel's 2023 microcode for Gather Data
///   Sampling slows, and whose gathers were slow beside the loads before
///   it. Measured on an Intel Xeon Ice Lake-SP (family 6, model 0x6A, a
///   KVM guest), one thread, `voxcast bench`, gathers → loads:
///   Marschner–Lobb 142–159 → 97–111 ms, the teapot 146–148 → 128–134 ms
///   (docs/engine.md, "Gathers or loads on Intel's Ice Lake").
/// * Every other Intel core keeps the gathers: on an Emerald Rapids
///   (family 6, model 0xCF) they were 5–13 % faster than the loads.
#[cfg_attr(not(all(packets, target_arch = "x86_64")), allow(dead_code))]
pub fn loads_beat_gathers(vendor: &[u8; 12], family: u32, model: u32) -> bool {
    match vendor {
        b"AuthenticAMD" | b"HygonGenuine" => true,
        // Linux's list of the cores Gather Data Sampling affects
        // (arch/x86/kernel/cpu/common.c): Skylake (client 0x4E, 0x5E;
        // server, with Cascade and Cooper Lake, 0x55), Kaby, Coffee and
        // Whiskey Lake (0x8E, 0x9E), Comet Lake (0xA5, 0xA6), Ice Lake
        // (0x7E client, 0x6A and 0x6C server), Tiger Lake (0x8C, 0x8D),
        // Rocket Lake (0xA7).
        b"GenuineIntel" => {
            family == 6
                && matches!(
                    model,
                    0x4E | 0x5E
                        | 0x55
                        | 0x8E
                        | 0x9E
                        | 0xA5
                        | 0xA6
                        | 0x7E
                        | 0x6A
                        | 0x6C
                        | 0x8C
                        | 0x8D
                        | 0xA7
                )
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::loads_beat_gathers;

    /// AArch64 runs the NEON packets unless the scalar loop is asked for
    /// (else every packet-against-scalar test there would check nothing).
    #[cfg(all(packets, target_arch = "aarch64"))]
    #[test]
    fn aarch64_runs_the_neon_packets() {
        use super::{level, Level};
        use crate::render::Simd;
        assert_eq!(level(Simd::Auto), Some(Level::Neon));
        assert_eq!(level(Simd::Scalar), None);
        assert_eq!(level(Simd::Avx512), None);
    }

    #[test]
    fn loads_where_the_gathers_are_slow() {
        let amd = b"AuthenticAMD";
        let intel = b"GenuineIntel";
        // AMD: Zen 3 (family 0x19) and Zen 5 (0x1A), any model.
        assert!(loads_beat_gathers(amd, 0x19, 0x01));
        assert!(loads_beat_gathers(amd, 0x1A, 0x02));
        assert!(loads_beat_gathers(b"HygonGenuine", 0x18, 0x00));
        // Intel: Ice Lake-SP (measured), Skylake-SP / Cascade Lake, Tiger
        // Lake take the loads ...
        assert!(loads_beat_gathers(intel, 6, 0x6A));
        assert!(loads_beat_gathers(intel, 6, 0x55));
        assert!(loads_beat_gathers(intel, 6, 0x8C));
        // ... Emerald Rapids (measured), Sapphire Rapids, Alder Lake and a
        // model 0x6A of another family keep the gathers.
        assert!(!loads_beat_gathers(intel, 6, 0xCF));
        assert!(!loads_beat_gathers(intel, 6, 0x8F));
        assert!(!loads_beat_gathers(intel, 6, 0x97));
        assert!(!loads_beat_gathers(intel, 0xF, 0x6A));
        assert!(!loads_beat_gathers(b"CentaurHauls", 6, 0x0F));
    }
}
