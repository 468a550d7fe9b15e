//! The plan of one out-of-core frame: the level each region of the volume
//! is read at, the bricks to march, and their visibility order.
//!
//! **Levels by region.** Where the store's levels nest (each level's chunk
//! covers whole chunks of the next finer one: the same chunk shape, or a
//! multiple, and integer downsampling factors — what `voxcast convert` and
//! other OME-Zarr writers make), the frame starts from the coarsest level's
//! chunks and splits a chunk into the finer level's chunks it covers while
//! its voxels are larger than a pixel where the chunk comes nearest the eye
//! (times `lod_scale`). Near the eye the frame reads the level
//! [`super::choose_level`] picks for the whole volume; further off, coarser
//! ones: what each region shows needs no more.
//!
//! **Regions.** Every brick owns the samples inside its *region*: the box
//! of the finest level rendered (the *base*) that its chunk covers, on the
//! base level's chunk boundaries. The regions tile the base level's sample
//! box whatever level each is read at, so every sample of a ray falls in
//! exactly one brick. Rays march the base level's step; a brick of a level
//! `stride` times coarser takes every `stride`-th of those samples, each
//! standing for `stride` steps (its opacity for that length): the same
//! stretch of the ray is covered once, by whichever level reads it.
//!
//! **Order.** Regions are cells of a grid on each level; a ray's distance
//! from the eye's cell never shrinks on any axis, so bricks sorted by that
//! distance (the sum over axes) among their siblings, depth first, meet
//! every ray in order.

use super::{sample_box, screen_rect};
use crate::camera::Camera;
use crate::volume::{ChunkRange, Level};
use glam::Vec3;

/// A level as one frame reads it, in terms of the base level.
pub(super) struct LevelGeo<'a> {
    pub(super) level: &'a Level,
    pub(super) lidx: usize,
    /// Level voxel coordinates of base voxel coordinates `p`:
    /// `p · scale + shift` (the identity at the base).
    scale: Vec3,
    shift: Vec3,
    identity: bool,
    /// This level takes every `stride`-th sample of the base step.
    pub(super) stride: u32,
    /// Voxels read around a region beyond what its interpolation needs: 1
    /// with shading (the central-difference gradient), else 0.
    g: u64,
}

impl<'a> LevelGeo<'a> {
    pub(super) fn new(levels: &'a [Level], base: usize, lidx: usize, shaded: bool) -> Self {
        let (b, l) = (&levels[base], &levels[lidx]);
        let identity = base == lidx;
        let scale = if identity {
            Vec3::ONE
        } else {
            b.spacing / l.spacing
        };
        let shift = if identity {
            Vec3::ZERO
        } else {
            (b.origin - l.origin) / l.spacing
        };
        let stride = (l.spacing.min_element() / b.spacing.min_element())
            .round()
            .max(1.0) as u32;
        LevelGeo {
            level: l,
            lidx,
            scale,
            shift,
            identity,
            stride,
            g: shaded as u64,
        }
    }

    /// Base voxel coordinates to this level's.
    #[inline]
    pub(super) fn to_level(&self, p: Vec3) -> Vec3 {
        if self.identity {
            p
        } else {
            p * self.scale + self.shift
        }
    }

    /// A direction in base voxel units to this level's.
    #[inline]
    pub(super) fn dir_to_level(&self, d: Vec3) -> Vec3 {
        if self.identity {
            d
        } else {
            d * self.scale
        }
    }

    /// This level's voxel coordinates to the base's.
    pub(super) fn to_base(&self, p: Vec3) -> Vec3 {
        if self.identity {
            p
        } else {
            (p - self.shift) / self.scale
        }
    }

    /// The voxels a brick reads to sample (and shade) anywhere in `own`
    /// (this level's voxel coordinates): `[lo, hi)`, clamped to the level,
    /// whose own clamping stands in beyond its edges. At the base level,
    /// where `own` is a chunk's box, that is the chunk and one voxel above
    /// it (one more on each side with shading).
    pub(super) fn data_box(&self, (lo, hi): (Vec3, Vec3)) -> ([u64; 3], [u64; 3]) {
        let d = self.level.dims;
        let g = self.g as f32;
        (
            std::array::from_fn(|a| (lo[a].floor() - g).max(0.0) as u64),
            std::array::from_fn(|a| ((hi[a].ceil() + 1.0 + g).max(1.0) as u64).min(d[a])),
        )
    }

    /// The chunks a voxel box meets.
    pub(super) fn chunks_of(&self, (lo, hi): ([u64; 3], [u64; 3])) -> Vec<[u64; 3]> {
        let ch = self.level.chunk.map(|c| c as u64);
        let a: [u64; 3] = std::array::from_fn(|i| lo[i] / ch[i]);
        let b: [u64; 3] = std::array::from_fn(|i| (hi[i] - 1) / ch[i]);
        cells(a, b.map(|v| v + 1)).collect()
    }
}

/// The indices of the box `[lo, hi)`, x fastest.
fn cells(lo: [u64; 3], hi: [u64; 3]) -> impl Iterator<Item = [u64; 3]> + Clone {
    (lo[2]..hi[2])
        .flat_map(move |z| (lo[1]..hi[1]).flat_map(move |y| (lo[0]..hi[0]).map(move |x| [x, y, z])))
}

/// Each level's downsampling factor per axis from the level before it
/// (level 0: 1), where level `l`'s chunks cover whole chunks of level
/// `l − 1`; `None` for a level that does not nest so.
pub(super) fn factors(levels: &[Level]) -> Vec<Option<[u64; 3]>> {
    let mut out = vec![Some([1; 3])];
    for w in levels.windows(2) {
        let (fine, coarse) = (&w[0], &w[1]);
        let f: Option<[u64; 3]> = (0..3)
            .map(|a| {
                let r = coarse.spacing[a] / fine.spacing[a];
                let f = r.round();
                let (ch_f, ch_c) = (fine.chunk[a] as u64, coarse.chunk[a] as u64);
                (f >= 1.0
                    && (r - f).abs() <= 1e-3 * f
                    && coarse.dims[a] == fine.dims[a].div_ceil(f as u64)
                    && (ch_c * f as u64).is_multiple_of(ch_f))
                .then_some(f as u64)
            })
            .collect::<Option<Vec<u64>>>()
            .map(|v| [v[0], v[1], v[2]]);
        out.push(f);
    }
    out
}

/// One brick of the plan.
pub(super) struct Brick {
    pub(super) lidx: usize,
    /// Pixel rectangle `[x0, x1) × [y0, y1)` its rays may cross.
    pub(super) rect: [u32; 4],
    /// The samples it owns: its region, in base voxel coordinates.
    pub(super) own: (Vec3, Vec3),
    /// The voxels it reads, `[lo, hi)` of its level, and their chunks.
    pub(super) dbox: ([u64; 3], [u64; 3]),
    pub(super) chunks: Vec<[u64; 3]>,
}

/// The frame's bricks in visibility order, and what was left out.
pub(super) struct Plan {
    pub(super) base: usize,
    pub(super) bricks: Vec<Brick>,
    /// Bricks considered (marched, empty, culled, occluded add up to it).
    pub(super) considered: usize,
    pub(super) culled: usize,
    pub(super) empty: usize,
    /// With [`Planner::resident`]: the chunks, not in memory, that finer
    /// regions would read — coarser levels first, then in visibility
    /// order, each once.
    pub(super) wanted: Vec<(usize, [u64; 3])>,
}

/// What the planner is given.
pub(super) struct Planner<'a> {
    pub(super) levels: &'a [Level],
    pub(super) cam: &'a Camera,
    pub(super) size: (u32, u32),
    /// The level chosen for the whole volume (the finest any region reads).
    pub(super) fine: usize,
    /// The coarsest level a region may read (`fine`: one level).
    pub(super) coarse: usize,
    pub(super) lod_scale: f32,
    pub(super) shaded: bool,
    /// Only chunks of `fine` inside this box (a part of a sort-last
    /// render; one level only).
    pub(super) part: Option<super::ChunkBox>,
    /// Render only what is in memory (a viewer that must not wait for a
    /// read): a chunk splits into its finer children only where every
    /// chunk they read is resident (`resident(level, chunk)`); the others
    /// go to [`Plan::wanted`].
    pub(super) resident: Option<&'a dyn Fn(usize, [u64; 3]) -> bool>,
}

/// What a walk of the level tree gathers.
struct Walk<'r> {
    cum: Vec<[u64; 3]>,
    ranges: &'r dyn Fn(usize) -> std::sync::Arc<Vec<ChunkRange>>,
    empty: &'r dyn Fn(&ChunkRange) -> bool,
    leaves: Vec<(usize, [u64; 3])>,
    culled: usize,
    wanted: Vec<(usize, [u64; 3])>,
}

impl Planner<'_> {
    /// Level `l`'s factor per axis relative to level 0.
    fn cumulative(&self, f: &[Option<[u64; 3]>], l: usize) -> [u64; 3] {
        (1..=l).fold([1; 3], |acc, i| {
            let fi = f[i].unwrap_or([1; 3]);
            std::array::from_fn(|a| acc[a] * fi[a])
        })
    }

    /// The bricks to march, in visibility order: the leaves of the level
    /// tree, without those off the image or known to be transparent
    /// (`ranges(l)`: what the store knows of level `l`'s chunks).
    pub(super) fn plan(
        &self,
        ranges: &dyn Fn(usize) -> std::sync::Arc<Vec<ChunkRange>>,
        empty: &dyn Fn(&ChunkRange) -> bool,
    ) -> Plan {
        let f = factors(self.levels);
        let mut walk = Walk {
            cum: (0..self.levels.len())
                .map(|l| self.cumulative(&f, l))
                .collect(),
            ranges,
            empty,
            leaves: Vec::new(),
            culled: 0,
            wanted: Vec::new(),
        };
        // Leaves do not depend on the base; their order does (it follows
        // the base's chunk boundaries). The base is `fine` unless every
        // region near the eye is off the image (or, resident only, not in
        // memory yet).
        self.walk(self.fine, &mut walk);
        let base = walk.leaves.iter().map(|l| l.0).min().unwrap_or(self.fine);
        if base != self.fine {
            walk.leaves.clear();
            walk.culled = 0;
            walk.wanted.clear();
            self.walk(base, &mut walk);
        }
        let Walk {
            cum,
            leaves,
            culled,
            mut wanted,
            ..
        } = walk;
        // Coarser first (a view refines evenly), in visibility order.
        let mut seen = std::collections::HashSet::new();
        wanted.retain(|k| seen.insert(*k));
        wanted.sort_by_key(|k| std::cmp::Reverse(k.0));
        let b = &self.levels[base];
        let sbox = sample_box(b.dims);
        let to_world = |p: Vec3| b.origin + p * b.spacing;
        let mut plan = Plan {
            base,
            bricks: Vec::with_capacity(leaves.len()),
            considered: leaves.len() + culled,
            culled,
            empty: 0,
            wanted,
        };
        let mut kept: Vec<Option<std::sync::Arc<Vec<ChunkRange>>>> = vec![None; self.levels.len()];
        for (l, c) in leaves {
            let geo = LevelGeo::new(self.levels, base, l, self.shaded);
            let own = self.region(l, c, base, &cum, sbox);
            if (0..3).any(|a| own.0[a] > own.1[a]) {
                plan.culled += 1;
                continue;
            }
            let Some(rect) = screen_rect(
                self.cam,
                to_world(own.0),
                to_world(own.1),
                self.size.0,
                self.size.1,
            ) else {
                plan.culled += 1;
                continue;
            };
            let dbox = geo.data_box((geo.to_level(own.0), geo.to_level(own.1)));
            let chunks = geo.chunks_of(dbox);
            let r = kept[l].get_or_insert_with(|| ranges(l));
            if chunks.iter().all(|&k| empty(&r[geo.level.chunk_index(k)])) {
                plan.empty += 1;
                continue;
            }
            plan.bricks.push(Brick {
                lidx: l,
                rect,
                own,
                dbox,
                chunks,
            });
        }
        plan
    }

    /// The region of level `l`'s chunk `c` in base voxel coordinates: the
    /// base voxels its chunk covers, clipped to the base's sample box.
    fn region(
        &self,
        l: usize,
        c: [u64; 3],
        base: usize,
        cum: &[[u64; 3]],
        (slo, shi): (Vec3, Vec3),
    ) -> (Vec3, Vec3) {
        let ch = self.levels[l].chunk;
        let lo = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
            (c[a] * ch[a] as u64 * (cum[l][a] / cum[base][a])) as f32
        }));
        let hi = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
            ((c[a] + 1) * ch[a] as u64 * (cum[l][a] / cum[base][a])) as f32
        }));
        (lo.max(slo), hi.min(shi))
    }

    /// Level `l`'s chunk `c` in world coordinates, over level 0's box (for
    /// the choice of level and the culling of whole subtrees).
    fn world_box(&self, l: usize, c: [u64; 3], cum: &[[u64; 3]]) -> (Vec3, Vec3) {
        let l0 = &self.levels[0];
        let ch = self.levels[l].chunk;
        let (slo, shi) = sample_box(l0.dims);
        let lo = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
            (c[a] * ch[a] as u64 * cum[l][a]) as f32
        }));
        let hi = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
            ((c[a] + 1) * ch[a] as u64 * cum[l][a]) as f32
        }));
        let (lo, hi) = (lo.max(slo), hi.min(shi));
        (l0.origin + lo * l0.spacing, l0.origin + hi * l0.spacing)
    }

    /// Whether level `l` is fine enough for the world box `(lo, hi)`.
    fn fine_enough(&self, l: usize, (lo, hi): (Vec3, Vec3)) -> bool {
        if l <= self.fine {
            return true;
        }
        let cam = self.cam;
        let nearest = cam.eye.clamp(lo, hi);
        let z = (nearest - cam.eye).dot(cam.forward).max(0.0);
        let pixel = cam.pixel_size_at(z) * self.lod_scale.max(1e-6);
        self.levels[l].spacing.min_element() <= pixel * (1.0 + 1e-4)
    }

    /// Sort key of level `l`'s chunk `c`: its grid distance from the eye's
    /// cell (on the base's chunk boundaries), or its position along the
    /// view for an orthographic camera.
    fn key(&self, l: usize, c: [u64; 3], base: usize, cum: &[[u64; 3]]) -> i64 {
        let cam = self.cam;
        if cam.is_orthographic() {
            return (0..3)
                .map(|a| {
                    if cam.forward[a] >= 0.0 {
                        c[a] as i64
                    } else {
                        -(c[a] as i64)
                    }
                })
                .sum();
        }
        let b = &self.levels[base];
        let eye = (cam.eye - b.origin) / b.spacing;
        let ch = self.levels[l].chunk;
        (0..3)
            .map(|a| {
                let cell = (ch[a] as u64 * (cum[l][a] / cum[base][a])) as f32;
                let e = (eye[a] / cell).floor() as i64;
                (c[a] as i64 - e).abs()
            })
            .sum()
    }

    /// The leaves `(level, chunk)` in visibility order for `base`, counting
    /// the subtrees off the image.
    fn walk(&self, base: usize, w: &mut Walk<'_>) {
        let top = self.coarse;
        let counts = self.levels[top].chunk_counts();
        let inside = |c: [u64; 3]| {
            self.part
                .is_none_or(|(lo, hi)| (0..3).all(|a| c[a] >= lo[a] && c[a] < hi[a]))
        };
        let mut roots: Vec<(i64, [u64; 3])> = cells([0; 3], counts)
            .filter(|&c| inside(c))
            .map(|c| (self.key(top, c, base, &w.cum), c))
            .collect();
        roots.sort_by_key(|r| r.0);
        for (_, c) in roots {
            self.descend(top, c, base, w);
        }
    }

    fn descend(&self, l: usize, c: [u64; 3], base: usize, w: &mut Walk<'_>) {
        let wbox = self.world_box(l, c, &w.cum);
        if l > self.fine
            && screen_rect(self.cam, wbox.0, wbox.1, self.size.0, self.size.1).is_none()
        {
            w.culled += 1;
            return;
        }
        if self.fine_enough(l, wbox) {
            w.leaves.push((l, c));
            return;
        }
        // The chunks of level l − 1 this one covers.
        let (ch, chf) = (self.levels[l].chunk, self.levels[l - 1].chunk);
        let fl: [u64; 3] = std::array::from_fn(|a| w.cum[l][a] / w.cum[l - 1][a]);
        let n = self.levels[l - 1].chunk_counts();
        let span: [(u64, u64); 3] = std::array::from_fn(|a| {
            let lo = c[a] * ch[a] as u64 * fl[a] / chf[a] as u64;
            let hi = ((c[a] + 1) * ch[a] as u64 * fl[a]).div_ceil(chf[a] as u64);
            (lo, hi.min(n[a]))
        });
        let kids = cells(span.map(|s| s.0), span.map(|s| s.1));
        if let Some(resident) = self.resident {
            // Split only where the children are in memory; else this
            // chunk stands for them, and what they lack is wanted. (Before
            // their sort keys: a child finer than the base has none.)
            let before = w.wanted.len();
            for k in kids.clone() {
                self.wants(l - 1, k, resident, w);
            }
            if w.wanted.len() > before {
                w.leaves.push((l, c));
                return;
            }
        }
        let mut kids: Vec<(i64, [u64; 3])> = kids
            .map(|k| (self.key(l - 1, k, base, &w.cum), k))
            .collect();
        kids.sort_by_key(|k| k.0);
        for (_, k) in kids {
            self.descend(l - 1, k, base, w);
        }
    }

    /// Adds to `w.wanted` the chunks level `l`'s chunk `k` reads (with
    /// every neighbour its border may reach) that are not resident, unless
    /// it is off the image or known to be transparent.
    fn wants(
        &self,
        l: usize,
        k: [u64; 3],
        resident: &dyn Fn(usize, [u64; 3]) -> bool,
        w: &mut Walk<'_>,
    ) {
        let wbox = self.world_box(l, k, &w.cum);
        if screen_rect(self.cam, wbox.0, wbox.1, self.size.0, self.size.1).is_none() {
            return;
        }
        let level = &self.levels[l];
        let (lo, hi) = level.chunk_box(k);
        // A region sits up to a voxel off its chunk (a coarser level's
        // half-voxel shift, rounded out), and reads one voxel more above
        // (two with shading) and one below with shading.
        let g = self.shaded as u64;
        let dbox = (
            lo.map(|v| v.saturating_sub(1 + g)),
            std::array::from_fn(|a| (hi[a] + 2 + g).min(level.dims[a])),
        );
        let geo = LevelGeo::new(self.levels, l, l, self.shaded);
        let chunks = geo.chunks_of(dbox);
        let r = (w.ranges)(l);
        if chunks.iter().all(|&q| (w.empty)(&r[level.chunk_index(q)])) {
            return;
        }
        for q in chunks {
            if !matches!(r[level.chunk_index(q)], ChunkRange::Fill(_)) && !resident(l, q) {
                w.wanted.push((l, q));
            }
        }
    }
}
