//! Particle-system clouds after S3 (Xie, Li, Kou): puffs filled with
//! particles that are generated frame by frame, grow to saturation, change
//! slowly and dissipate from the low-opacity edge towards the core; the
//! particles are splatted into a density grid with a smooth kernel, and
//! noise erodes the edges so they are wispy rather than blobby.
//!
//! The cloud amount is the number of live particles. Per frame (S3 eqs. 2–6):
//!
//! * growth (`frame < t_v`): `N_num = N_frame + ⌊rand·N_max⌋` candidates
//!   (eq. 2), each kept only inside its puff's sphere (eq. 3), so a frame adds
//!   at most the saturation amount `N_s = N_frame + N_max` (eq. 4);
//! * slow change (`t_v ≤ frame < t_e`): particles whose life has run out
//!   die, and `N_snum = N_frame + ⌊rand·N_min⌋` candidates replace them, with
//!   `N_frame` the frame's turnover (the dead), so the amount grows by at
//!   most `N_min` a frame (eq. 5);
//! * dissipation (`frame ≥ t_e`): `N_snum = N_fext + ⌊rand(a)·N_min⌋ −
//!   ⌊rand(b)·N_ext⌋` (eq. 6): up to `N_min` candidates are added and
//!   `⌊rand(b)·N_ext⌋` particles removed, the lowest-opacity ones first —
//!   those farthest out in their puff, since the density falls from the core
//!   to the edge.

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use voxcast::error::{Error, Result};
use voxcast::volume::{Volume, VoxelData};

/// A cloud type: how puffs are laid out and shaped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CloudType {
    /// Heaped clouds: clusters of round puffs with flat bases, bigger puffs
    /// at the bottom and smaller ones piled on top.
    Cumulus,
    /// A low, wide, flat layer of squashed puffs.
    Stratus,
    /// Cumulus clouds of many more, smaller puffs that break up into
    /// patches (altocumulus / "mackerel sky").
    Altocumulus,
}

impl CloudType {
    pub const ALL: [CloudType; 3] = [
        CloudType::Cumulus,
        CloudType::Stratus,
        CloudType::Altocumulus,
    ];

    pub fn name(self) -> &'static str {
        match self {
            CloudType::Cumulus => "cumulus",
            CloudType::Stratus => "stratus",
            CloudType::Altocumulus => "altocumulus",
        }
    }

    pub fn parse(s: &str) -> Result<CloudType> {
        CloudType::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "cloud type `{s}`: expected one of {}",
                    CloudType::ALL.map(|t| t.name()).join(", ")
                ))
            })
    }
}

/// The particle-count parameters of S3 eqs. 2–6, and the phase lengths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Counts {
    /// `N_frame`: base candidates per growth frame (eq. 2).
    pub n_frame: u32,
    /// `N_max`: largest random extra per growth frame (eq. 2).
    pub n_max: u32,
    /// `N_min`: largest random extra per frame after saturation (eqs. 5, 6).
    pub n_min: u32,
    /// `N_ext`: most particles removed per dissipating frame (eq. 6).
    pub n_ext: u32,
    /// Frames of growth (`t_v`).
    pub t_v: u32,
    /// Frame where dissipation starts (`t_e`).
    pub t_e: u32,
}

/// A cloud puff: a sphere (squashed in z by `squash`) filled with particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Puff {
    /// Centre `(a, b, c)` in voxels.
    pub centre: Vec3,
    /// Radius `R` in voxels.
    pub radius: f32,
    /// Vertical scale of the sphere (1 round, < 1 flat).
    pub squash: f32,
    /// Height (voxels) below which the puff is cut off: flat cloud bases.
    pub base: f32,
    /// Density weight of its particles (1; from the weather model's cloud
    /// water for `--from-wrf`).
    pub weight: f32,
}

impl Puff {
    /// Normalised radius of a point at `offset` from the centre: ≤ 1 inside
    /// the puff's (squashed) sphere (S3 eq. 3).
    #[inline]
    pub fn radius_of(&self, offset: Vec3) -> f32 {
        (Vec3::new(offset.x, offset.y, offset.z / self.squash)).length() / self.radius
    }
}

/// A particle (S3 eq. 1 and its attributes: position, size, velocity, life).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    /// Index of its puff.
    pub puff: u32,
    /// Position relative to the puff's centre, voxels.
    pub offset: Vec3,
    /// Splat radius, voxels.
    pub size: f32,
    /// Drift within the puff, voxels per frame.
    pub velocity: Vec3,
    /// Frames left to live.
    pub life: u32,
    /// Frames lived (new particles fade in).
    pub age: u32,
}

/// What one frame did to the particle count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameCounts {
    /// Candidates generated (eq. 2, 5 or 6).
    pub generated: u32,
    /// Candidates kept inside their puff's sphere (eq. 3).
    pub kept: u32,
    /// Particles whose life ran out.
    pub died: u32,
    /// Particles removed by dissipation (eq. 6).
    pub dissipated: u32,
    /// Live particles after the frame.
    pub total: u32,
}

/// Options of a cloud simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudOptions {
    pub kind: CloudType,
    /// Density grid size (x, y, z); z is up.
    pub grid: [usize; 3],
    pub seed: u64,
    /// Frames written; 1 writes the cloud at saturation.
    pub frames: u32,
}

impl Default for CloudOptions {
    fn default() -> Self {
        CloudOptions {
            kind: CloudType::Cumulus,
            grid: [400, 400, 60],
            seed: 1,
            frames: 1,
        }
    }
}

/// A small seeded PRNG (SplitMix64): the same seed gives the same cloud.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x5851_F42D_4C95_7F2D)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
}

/// The particle system of one cloud field.
#[derive(Clone, Debug)]
pub struct CloudSim {
    pub options: CloudOptions,
    pub counts: Counts,
    pub puffs: Vec<Puff>,
    pub particles: Vec<Particle>,
    /// Horizontal wind: every puff drifts by this much a frame (voxels).
    pub wind: Vec3,
    /// Frames simulated so far.
    pub frame: u32,
    rng: Rng,
    /// The particles the last dissipating frame removed (for checks).
    pub last_removed: Vec<Particle>,
}

/// Frames simulated before the single frame written when `frames` is 1.
const SINGLE_GROWTH: u32 = 24;

impl CloudSim {
    /// Lays out the puffs of `options.kind` over the grid.
    pub fn new(options: CloudOptions) -> Result<CloudSim> {
        Self::check(&options)?;
        let mut rng = Rng::new(options.seed);
        let puffs = layout(options.kind, options.grid, &mut rng);
        Ok(Self::with_puffs(options, puffs, rng))
    }

    /// The paper's path (S3): particles seeded where a weather model has
    /// cloud water. Every cell of `field` (e.g. WRF QCLOUD) above 1 % of
    /// its maximum becomes a puff at the same place in the output grid,
    /// its radius the cell's size and its particles' density weight the
    /// cell's value over the maximum; the field's extent maps onto the
    /// whole grid.
    pub fn from_field(options: CloudOptions, field: &Volume) -> Result<CloudSim> {
        Self::check(&options)?;
        let mut rng = Rng::new(options.seed);
        let fd = field.dims();
        let max = field.stats().max;
        if !(max > 0.0 && max.is_finite()) {
            return Err(Error::invalid(format!(
                "{}: the field has no positive value to seed cloud particles from",
                field.name.as_deref().unwrap_or("field")
            )));
        }
        let g = options.grid.map(|d| d as f32);
        let scale = Vec3::new(
            g[0] / fd[0] as f32,
            g[1] / fd[1] as f32,
            g[2] / fd[2] as f32,
        );
        let mut puffs = Vec::new();
        for k in 0..fd[2] {
            for j in 0..fd[1] {
                for i in 0..fd[0] {
                    let q = field.value(i, j, k);
                    if q.is_nan() || q <= 0.01 * max {
                        continue;
                    }
                    let w = q / max;
                    let r = scale.x.max(scale.y) * (0.8 + 0.6 * rng.f32());
                    let c = (Vec3::new(i as f32, j as f32, k as f32) + Vec3::splat(0.5)) * scale
                        + Vec3::new(rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), 0.0) * scale;
                    puffs.push(Puff {
                        centre: c,
                        radius: r,
                        squash: (1.5 * scale.z / r).clamp(0.1, 1.0),
                        base: 0.0,
                        weight: w.sqrt(),
                    });
                }
            }
        }
        if puffs.is_empty() {
            return Err(Error::invalid(
                "the field holds no cloud to seed particles from",
            ));
        }
        let mut sim = Self::with_puffs(options, puffs, rng);
        sim.wind = Vec3::ZERO;
        Ok(sim)
    }

    fn check(options: &CloudOptions) -> Result<()> {
        let [nx, ny, nz] = options.grid;
        let n = nx.checked_mul(ny).and_then(|n| n.checked_mul(nz));
        if nx < 8 || ny < 8 || nz < 8 || n.is_none_or(|n| n > 1 << 30) {
            return Err(Error::invalid(format!(
                "cloud grid {nx}×{ny}×{nz}: each side must be at least 8 voxels and the grid at most 2³⁰ voxels"
            )));
        }
        if options.frames == 0 || options.frames > 10_000 {
            return Err(Error::invalid(format!(
                "frames {}: must be 1…10000",
                options.frames
            )));
        }
        Ok(())
    }

    fn with_puffs(options: CloudOptions, puffs: Vec<Puff>, mut rng: Rng) -> CloudSim {
        // The total volume of the puffs sets the particle budget, so a
        // bigger grid gets proportionally more particles.
        let puff_volume: f32 = puffs
            .iter()
            .map(|p| 4.19 * p.radius.powi(3) * p.squash)
            .sum();
        let growth = if options.frames == 1 {
            SINGLE_GROWTH
        } else {
            (options.frames * 2 / 5).max(1)
        };
        let slow = if options.frames == 1 {
            0
        } else {
            (options.frames / 4).max(1)
        };
        // About one particle per 60 voxels of puff at saturation.
        let saturated = (puff_volume / 60.0)
            .max(8.0 * puffs.len() as f32)
            .clamp(200.0, 400_000.0);
        let per_frame = saturated / growth as f32;
        let n_frame = (per_frame * 0.7) as u32;
        let n_max = (per_frame * 0.6) as u32;
        let n_min = (per_frame * 0.05).max(1.0) as u32;
        let dissipating = options.frames.saturating_sub(growth + slow).max(1);
        // Enough removal that the cloud is gone by the last frame.
        let n_ext = ((saturated * 2.6) / dissipating as f32) as u32 + n_min;
        let counts = Counts {
            n_frame,
            n_max,
            n_min,
            n_ext,
            t_v: growth,
            t_e: growth + slow,
        };
        CloudSim {
            wind: Vec3::new(rng.range(-0.4, 0.4), rng.range(-0.4, 0.4), 0.0),
            options,
            counts,
            puffs,
            particles: Vec::new(),
            frame: 0,
            rng,
            last_removed: Vec::new(),
        }
    }

    /// World (voxel) position of a particle.
    #[inline]
    pub fn position(&self, p: &Particle) -> Vec3 {
        self.puffs[p.puff as usize].centre + p.offset
    }

    /// Generates `n` candidates (S3 eq. 1) and keeps those inside their
    /// puff's sphere (eq. 3). Returns the number kept.
    fn generate(&mut self, n: u32) -> u32 {
        let mut kept = 0;
        for _ in 0..n {
            // Puffs are chosen in proportion to their volume.
            let i = self.pick_puff();
            let puff = self.puffs[i];
            // S3 eq. 1: X = a + Random(i)·R·sinθ·cosφ, Y = b + Random(i)·R·cosθ,
            // Z = c + Random(i)·R·sinθ·sinφ. Random(i) uniform in radius gives
            // a density ∝ 1/r²: a dense core and a sparse edge. Here z is up,
            // so the polar axis is z; a turbulent jitter of up to a quarter
            // radius lets some candidates fall outside, and eq. 3 removes them.
            let r = self.rng.f32() * puff.radius;
            let cos_t = self.rng.range(-1.0, 1.0);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let phi = self.rng.range(0.0, std::f32::consts::TAU);
            let dir = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
            let jitter = Vec3::new(
                self.rng.range(-1.0, 1.0),
                self.rng.range(-1.0, 1.0),
                self.rng.range(-1.0, 1.0),
            ) * (0.25 * puff.radius);
            let mut offset = dir * r + jitter;
            offset.z *= puff.squash;
            // S3 eq. 3: only candidates inside the sphere are cloud particles.
            if puff.radius_of(offset) > 1.0 || puff.centre.z + offset.z < puff.base {
                continue;
            }
            let rn = puff.radius_of(offset);
            let size = puff.radius * self.rng.range(0.18, 0.32) * (1.15 - 0.5 * rn);
            let velocity = Vec3::new(
                self.rng.range(-1.0, 1.0),
                self.rng.range(-1.0, 1.0),
                self.rng.range(-0.5, 1.0),
            ) * 0.08;
            let life = self.counts.t_v + (self.rng.f32() * 2.0 * self.counts.t_v as f32) as u32;
            self.particles.push(Particle {
                puff: i as u32,
                offset,
                size: size.max(1.5),
                velocity,
                life: life.max(1),
                age: 0,
            });
            kept += 1;
        }
        kept
    }

    fn pick_puff(&mut self) -> usize {
        let total: f32 = self.puffs.iter().map(|p| p.radius.powi(3) * p.squash).sum();
        let mut u = self.rng.f32() * total;
        for (i, p) in self.puffs.iter().enumerate() {
            u -= p.radius.powi(3) * p.squash;
            if u <= 0.0 {
                return i;
            }
        }
        self.puffs.len() - 1
    }

    /// Advances one frame: moves and ages the particles, then applies the
    /// phase's count rule (S3 eqs. 2–6).
    pub fn step(&mut self) -> FrameCounts {
        let c = self.counts;
        let f = self.frame;
        // Slow change within the puff: particles drift and bounce back off
        // the sphere, so they stay cloud particles (eq. 3) as they move.
        for p in self.particles.iter_mut() {
            let puff = self.puffs[p.puff as usize];
            let next = p.offset + p.velocity;
            if puff.radius_of(next) <= 1.0 && puff.centre.z + next.z >= puff.base {
                p.offset = next;
            } else {
                p.velocity = -p.velocity;
            }
            p.age += 1;
        }
        for puff in self.puffs.iter_mut() {
            puff.centre += self.wind;
            puff.base += self.wind.z;
        }
        let mut out = FrameCounts::default();
        self.last_removed.clear();
        if f < c.t_v {
            // Growth, eq. 2 (bounded by N_s, eq. 4).
            out.generated = c.n_frame + (self.rng.f32() * c.n_max as f32) as u32;
            out.kept = self.generate(out.generated);
        } else if f < c.t_e {
            // Slow change, eq. 5: the dead are replaced, plus up to N_min.
            let before = self.particles.len();
            self.particles.retain(|p| p.age < p.life);
            out.died = (before - self.particles.len()) as u32;
            out.generated = out.died + (self.rng.f32() * c.n_min as f32) as u32;
            out.kept = self.generate(out.generated);
        } else {
            // Dissipation, eq. 6, from the low-opacity edge inwards.
            let a = self.rng.f32();
            let b = self.rng.f32();
            let remove = ((b * c.n_ext as f32) as usize).min(self.particles.len());
            out.dissipated = remove as u32;
            if remove > 0 {
                let puffs = &self.puffs;
                // Outermost first: sort by normalised radius, descending.
                let key = |p: &Particle| puffs[p.puff as usize].radius_of(p.offset);
                self.particles
                    .sort_unstable_by(|x, y| key(y).total_cmp(&key(x)));
                self.last_removed = self.particles.drain(..remove).collect();
            }
            out.generated = (a * c.n_min as f32) as u32;
            // New particles of a dissipating cloud form only in its core.
            out.kept = self.generate_core(out.generated);
        }
        self.frame += 1;
        out.total = self.particles.len() as u32;
        out
    }

    /// Generation during dissipation: candidates as in eq. 1, kept only in
    /// the inner half of the sphere (eq. 3 with R/2), where the cloud still
    /// holds water.
    fn generate_core(&mut self, n: u32) -> u32 {
        let start = self.particles.len();
        self.generate(n);
        let puffs = &self.puffs;
        let tail: Vec<Particle> = self.particles.drain(start..).collect();
        let kept: Vec<Particle> = tail
            .into_iter()
            .filter(|p| puffs[p.puff as usize].radius_of(p.offset) <= 0.5)
            .collect();
        let k = kept.len() as u32;
        self.particles.extend(kept);
        k
    }

    /// Splats the particles into the density grid (values 0…1) and erodes
    /// the edges with noise.
    pub fn density(&self) -> Result<Volume> {
        let [nx, ny, nz] = self.options.grid;
        let seed = self.options.seed;
        // Per particle: position, radius and weight (new particles fade in
        // over three frames so growth is smooth in an animation).
        let splats: Vec<(Vec3, f32, f32)> = self
            .particles
            .iter()
            .map(|p| {
                let w = ((p.age + 1) as f32 / 3.0).min(1.0) * self.puffs[p.puff as usize].weight;
                (self.position(p), p.size, w)
            })
            .collect();
        // Bin the particles by the z-slices they touch, so each slice is
        // built by one task without locks.
        let mut by_slice: Vec<Vec<u32>> = vec![Vec::new(); nz];
        for (i, (c, r, _)) in splats.iter().enumerate() {
            let k0 = (c.z - r).ceil().max(0.0) as usize;
            let k1 = ((c.z + r).floor().min(nz as f32 - 1.0)).max(-1.0);
            if k1 < 0.0 {
                continue;
            }
            for s in by_slice.iter_mut().take(k1 as usize + 1).skip(k0) {
                s.push(i as u32);
            }
        }
        let mut data = vec![0f32; nx * ny * nz];
        data.par_chunks_mut(nx * ny)
            .zip(by_slice.par_iter())
            .enumerate()
            .for_each(|(k, (slice, list))| {
                let z = k as f32;
                for &i in list {
                    let (c, r, w) = splats[i as usize];
                    let dz2 = (z - c.z) * (z - c.z);
                    let rr = r * r;
                    let rem = rr - dz2;
                    if rem <= 0.0 {
                        continue;
                    }
                    let ext = rem.sqrt();
                    let j0 = (c.y - ext).ceil().max(0.0) as usize;
                    let j1 = (c.y + ext).floor().min(ny as f32 - 1.0);
                    let i0 = (c.x - ext).ceil().max(0.0) as usize;
                    let i1 = (c.x + ext).floor().min(nx as f32 - 1.0);
                    if j1 < 0.0 || i1 < 0.0 {
                        continue;
                    }
                    let inv = 1.0 / rr;
                    for j in j0..=j1 as usize {
                        let dy = j as f32 - c.y;
                        let row = &mut slice[j * nx..(j + 1) * nx];
                        for (ii, v) in row.iter_mut().enumerate().take(i1 as usize + 1).skip(i0) {
                            let dx = ii as f32 - c.x;
                            let q = 1.0 - (dx * dx + dy * dy + dz2) * inv;
                            if q > 0.0 {
                                // A smooth, compactly supported kernel
                                // (Wyvill's (1 − d²/r²)³).
                                *v += w * q * q * q;
                            }
                        }
                    }
                }
            });
        // Coverage saturates where particles overlap, then noise erodes the
        // thin parts: where the coverage is low, low noise removes it, which
        // breaks the edges into wisps while the core stays whole.
        let freq = 1.0 / 30.0;
        data.par_chunks_mut(nx * ny)
            .enumerate()
            .for_each(|(k, slice)| {
                for j in 0..ny {
                    for i in 0..nx {
                        let v = &mut slice[j * nx + i];
                        if *v <= 0.0 {
                            continue;
                        }
                        let cov = 1.0 - (-1.2 * *v).exp();
                        let p = Vec3::new(i as f32, j as f32, k as f32 * 1.6) * freq;
                        let detail = 0.6 * fbm(p, seed) + 0.4 * (1.0 - worley(p * 1.7, seed));
                        // Remap: the erosion threshold is high where the
                        // coverage is low (edges), low in the core.
                        let e = 0.85 * (1.0 - detail);
                        let d = ((cov - e * (1.0 - cov)) / (1.0 - e * (1.0 - cov))).max(0.0);
                        *v = d.min(1.0);
                    }
                }
            });
        let mut vol = Volume::new(
            [nx, ny, nz],
            Vec3::ONE,
            Vec3::ZERO,
            VoxelData::F32(data.into()),
        )?;
        vol.name = Some("density".into());
        Ok(vol)
    }

    /// The frames to simulate between written frames and how many are
    /// written: `frames` > 1 writes every frame of the life cycle; 1 writes
    /// the saturated cloud after the growth phase.
    pub fn schedule(&self) -> (u32, u32) {
        if self.options.frames == 1 {
            (self.counts.t_v, 1)
        } else {
            (1, self.options.frames)
        }
    }
}

/// Puff layouts per cloud type, in voxel coordinates of a grid `dims`
/// (z up).
fn layout(kind: CloudType, dims: [usize; 3], rng: &mut Rng) -> Vec<Puff> {
    let [nx, ny, nz] = dims.map(|d| d as f32);
    let h = nz;
    let mut puffs = Vec::new();
    match kind {
        CloudType::Cumulus | CloudType::Altocumulus => {
            let alto = kind == CloudType::Altocumulus;
            // Clouds per field and their size, from the grid's footprint and
            // height: a cumulus's width is a few times its depth.
            let depth = h * if alto { 0.45 } else { 0.9 };
            let scale = (depth * if alto { 1.2 } else { 1.6 }).min(nx.min(ny) * 0.3);
            let n_clouds = ((nx * ny) / (scale * scale * if alto { 2.0 } else { 3.5 }))
                .round()
                .clamp(1.0, 60.0) as usize;
            let base = h * if alto { 0.35 } else { 0.08 };
            let mut centres: Vec<(f32, f32)> = Vec::new();
            for _ in 0..n_clouds {
                // Spread out: the best of a few random tries.
                let mut best = (nx * 0.5, ny * 0.5);
                let mut best_d = -1.0;
                for _ in 0..12 {
                    let c = (
                        rng.range(scale, (nx - scale).max(scale + 1.0)),
                        rng.range(scale, (ny - scale).max(scale + 1.0)),
                    );
                    let d = centres
                        .iter()
                        .map(|o| (o.0 - c.0).hypot(o.1 - c.1))
                        .fold(f32::INFINITY, f32::min);
                    if d > best_d {
                        best_d = d;
                        best = c;
                    }
                }
                centres.push(best);
                let size = rng.range(0.65, 1.0);
                let width = scale * size;
                let top = base + depth * size;
                // A row of base puffs, then smaller ones heaped on top.
                let n_base = rng.range(4.0, 7.0) as usize;
                for _ in 0..n_base {
                    let r = width * rng.range(0.35, 0.5);
                    puffs.push(Puff {
                        centre: Vec3::new(
                            best.0 + rng.range(-0.6, 0.6) * width,
                            best.1 + rng.range(-0.6, 0.6) * width,
                            base + r * 0.55,
                        ),
                        radius: r,
                        squash: (((top - base) * 0.5) / r).min(1.0),
                        base,
                        weight: 1.0,
                    });
                }
                let n_top = rng.range(2.0, 5.0) as usize;
                for _ in 0..n_top {
                    let r = width * rng.range(0.25, 0.38);
                    let zc = (top - r).max(base + r * 0.8);
                    puffs.push(Puff {
                        centre: Vec3::new(
                            best.0 + rng.range(-0.35, 0.35) * width,
                            best.1 + rng.range(-0.35, 0.35) * width,
                            zc,
                        ),
                        radius: r,
                        squash: ((h - 2.0 - zc) / r).clamp(0.4, 1.0),
                        base,
                        weight: 1.0,
                    });
                }
            }
        }
        CloudType::Stratus => {
            // One layer over most of the field: many wide flat puffs, thin
            // where they thin out, with a few holes.
            let layer = h * 0.45;
            let thick = h * 0.22;
            let r_mean = (nx.min(ny) * 0.09).max(4.0);
            let n = ((nx * ny) / (r_mean * r_mean * 1.1)).clamp(4.0, 4000.0) as usize;
            for _ in 0..n {
                let r = r_mean * rng.range(0.7, 1.3);
                let x = rng.range(0.08, 0.92) * nx;
                let y = rng.range(0.08, 0.92) * ny;
                puffs.push(Puff {
                    centre: Vec3::new(x, y, layer + rng.range(-0.25, 0.25) * thick),
                    radius: r,
                    squash: (thick / r).min(1.0),
                    base: 0.0,
                    weight: 1.0,
                });
            }
        }
    }
    puffs
}

/// Hash of an integer lattice point and a seed to [0, 1).
#[inline]
fn hash3(x: i32, y: i32, z: i32, seed: u64) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x8DA6_B343)
        ^ (y as u64).wrapping_mul(0xD816_3841)
        ^ (z as u64).wrapping_mul(0xCB1A_B31F)
        ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    h = (h ^ (h >> 33)).wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h = (h ^ (h >> 33)).wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^= h >> 33;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in [0, 1).
#[inline]
fn value_noise(p: Vec3, seed: u64) -> f32 {
    let f = p.floor();
    let t = p - f;
    let s = t * t * (Vec3::splat(3.0) - 2.0 * t);
    let (x, y, z) = (f.x as i32, f.y as i32, f.z as i32);
    let l = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let c = |dx, dy, dz| hash3(x + dx, y + dy, z + dz, seed);
    l(
        l(
            l(c(0, 0, 0), c(1, 0, 0), s.x),
            l(c(0, 1, 0), c(1, 1, 0), s.x),
            s.y,
        ),
        l(
            l(c(0, 0, 1), c(1, 0, 1), s.x),
            l(c(0, 1, 1), c(1, 1, 1), s.x),
            s.y,
        ),
        s.z,
    )
}

/// Fractal Brownian motion: four octaves of value noise, in [0, 1).
pub fn fbm(p: Vec3, seed: u64) -> f32 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut q = p;
    for o in 0..4u64 {
        sum += amp * value_noise(q, seed.wrapping_add(o));
        q *= 2.03;
        amp *= 0.5;
    }
    sum / 0.9375
}

/// Worley (cellular) noise: distance to the nearest feature point, about
/// 0…1; `1 − worley` gives round billows.
pub fn worley(p: Vec3, seed: u64) -> f32 {
    let f = p.floor();
    let (x, y, z) = (f.x as i32, f.y as i32, f.z as i32);
    let mut best = f32::INFINITY;
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (cx, cy, cz) = (x + dx, y + dy, z + dz);
                let fp = Vec3::new(
                    cx as f32 + hash3(cx, cy, cz, seed ^ 1),
                    cy as f32 + hash3(cx, cy, cz, seed ^ 2),
                    cz as f32 + hash3(cx, cy, cz, seed ^ 3),
                );
                best = best.min((fp - p).length_squared());
            }
        }
    }
    best.sqrt().min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sim(kind: CloudType, frames: u32) -> CloudSim {
        CloudSim::new(CloudOptions {
            kind,
            grid: [96, 96, 24],
            seed: 7,
            frames,
        })
        .unwrap()
    }

    #[test]
    fn counts_follow_growth_saturation_and_dissipation() {
        let mut s = sim(CloudType::Cumulus, 20);
        let c = s.counts;
        assert_eq!((c.t_v, c.t_e), (8, 13));
        let n_s = c.n_frame + c.n_max; // S3 eq. 4
        let mut prev = 0u32;
        let mut history = Vec::new();
        for f in 0..20 {
            let out = s.step();
            history.push(out);
            if f < c.t_v {
                // Eq. 2: N_frame ≤ N_num < N_s, kept ≤ generated, and the
                // amount grows every frame.
                assert!(out.generated >= c.n_frame && out.generated < n_s, "{out:?}");
                assert!(out.kept <= out.generated);
                assert!(out.kept > 0 && out.total == prev + out.kept);
                assert_eq!(out.died + out.dissipated, 0);
            } else if f < c.t_e {
                // Eq. 5: turnover plus at most N_min.
                assert!(out.generated < out.died + c.n_min.max(1));
                assert!(out.total <= prev + c.n_min, "{out:?} after {prev}");
                assert_eq!(out.total, prev - out.died + out.kept);
            } else {
                // Eq. 6: N_fext + rand·N_min − rand·N_ext.
                assert!(out.dissipated < c.n_ext && out.generated < c.n_min.max(1));
                assert_eq!(out.total, prev + out.kept - out.dissipated);
            }
            prev = out.total;
        }
        // Saturated amount bounded by t_v·N_s; at the end it has faded.
        let peak = history.iter().map(|h| h.total).max().unwrap();
        assert!(peak <= c.t_v * n_s + c.n_min * (c.t_e - c.t_v));
        assert!(history[c.t_v as usize - 1].total as f32 > 0.5 * (c.t_v * c.n_frame) as f32);
        assert!(prev < peak / 4, "{prev} of {peak} left");
    }

    #[test]
    fn every_particle_lies_in_its_puff() {
        for kind in CloudType::ALL {
            let mut s = sim(kind, 12);
            for _ in 0..12 {
                s.step();
                for p in &s.particles {
                    let puff = s.puffs[p.puff as usize];
                    assert!(puff.radius_of(p.offset) <= 1.0 + 1e-5, "{kind:?} {p:?}");
                    assert!(puff.centre.z + p.offset.z >= puff.base - 1e-3);
                }
            }
        }
    }

    #[test]
    fn dissipation_removes_the_edge_first() {
        let mut s = sim(CloudType::Cumulus, 20);
        let mut removed = Vec::new();
        for _ in 0..16 {
            s.step();
            removed.extend(
                s.last_removed
                    .iter()
                    .map(|p| s.puffs[p.puff as usize].radius_of(p.offset)),
            );
            if removed.len() > 50 {
                break;
            }
        }
        assert!(
            removed.len() > 50,
            "dissipation removed only {}",
            removed.len()
        );
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let kept: Vec<f32> = s
            .particles
            .iter()
            .map(|p| s.puffs[p.puff as usize].radius_of(p.offset))
            .collect();
        assert!(
            mean(&removed) > mean(&kept) + 0.1,
            "removed {} kept {}",
            mean(&removed),
            mean(&kept)
        );
    }

    #[test]
    fn same_seed_same_grid_and_density_in_range() {
        let run = |seed| {
            let mut s = CloudSim::new(CloudOptions {
                seed,
                grid: [128, 128, 32],
                frames: 1,
                kind: CloudType::Cumulus,
            })
            .unwrap();
            let (n, _) = s.schedule();
            for _ in 0..n {
                s.step();
            }
            s.density().unwrap()
        };
        let (a, b, c) = (run(3), run(3), run(4));
        assert_eq!(a.data(), b.data());
        assert_ne!(a.data(), c.data());
        let st = a.stats();
        assert!(st.min >= 0.0 && st.max <= 1.0 && st.max > 0.5, "{st:?}");
        // Cloud fills part of the field, not all of it.
        assert!(st.mean > 0.01 && st.mean < 0.5, "{st:?}");
    }

    #[test]
    fn noise_is_in_range() {
        for i in 0..1000 {
            let p = Vec3::new(i as f32 * 0.37, i as f32 * 0.11, i as f32 * 0.053);
            let (f, w) = (fbm(p, 1), worley(p, 1));
            assert!((0.0..=1.0).contains(&f) && (0.0..=1.0).contains(&w));
        }
    }
}
