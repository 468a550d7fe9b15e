//! Sort-last parallel rendering, as ParaView and VisIt do it with IceT: the
//! volume is split into one sub-domain per process, each renders its part
//! with the out-of-core ray caster, and the partial images are composited
//! with `over` in visibility order.
//!
//! 1. **Decomposition** ([`Decomposition`]): a k-d tree over the chunks of
//!    the rendered level. Each cut runs along the axis with the most chunks
//!    and balances the chunks that may show under the transfer function
//!    (their value ranges, from the store or measured), so every process
//!    marches about as many non-empty bricks. A part is a box of whole
//!    chunks; its bricks read a border of one voxel (two with shading)
//!    from the chunks around it — the ghost layer — so the reconstruction
//!    is seamless.
//! 2. **Render** ([`crate::render::outofcore::OutOfCore::render_part`]):
//!    every ray's samples sit on the one grid `t₀ + k·step` wherever the
//!    cuts fall, and each sample belongs to exactly one part, so the parts
//!    hold disjoint stretches of every ray.
//! 3. **Compositing** ([`composite`]): radix-k (Peterka et al. 2009), of
//!    which binary swap (all k = 2) and direct send (one round, k = N) are
//!    the two ends. The process count is factored into rounds
//!    `N = k₀·k₁·…`; the tree is built so that the processes of one round's
//!    group are the children of one node, which is what lets the group
//!    composite its piece of the image in the node's visibility order. In
//!    each round every process keeps 1/k of the image piece it holds and
//!    sends the rest to its group, so no process holds more than its share
//!    of the image after the first round; a piece travels only from its
//!    first to its last pixel that is not transparent. The pieces are
//!    gathered on process 0 at the end.
//!
//! The transport is the [`Exchange`] trait: MPI in the command-line tool
//! (its `mpi` feature), threads in [`ThreadExchange`] (tests, and a check
//! of the algorithm without MPI).
//!
//! Early ray termination is off in a sort-last render (a part does not see
//! the opacity in front of it), so the picture is the one-process render's
//! with `ert = 1`; only the uniform marchers (`uniform`, `jitter`) run.

mod exchange;
// Its tests render, so they are integration tests (tests/sortlast.rs): see
// outofcore/mod.rs.

pub use exchange::{Exchange, ThreadExchange};

use crate::camera::{Camera, CameraParams};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::render::outofcore::{self, ChunkBox, OutOfCore, OutOfCoreStats};
use crate::render::{RenderParams, RenderStats};
use crate::transfer::TransferFunction;
use crate::volume::Level;
use glam::Vec3;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// The rounds of radix-k for `n` processes: `n`'s prime factors, smallest
/// first (all twos: binary swap). `[]` for one process.
pub fn rounds(n: usize) -> Vec<usize> {
    let mut f = Vec::new();
    let (mut n, mut p) = (n.max(1), 2);
    while n > 1 {
        while n % p == 0 {
            f.push(p);
            n /= p;
        }
        p += 1;
        if p * p > n && n > 1 {
            f.push(n);
            break;
        }
    }
    f
}

/// A node of the k-d tree: a box of chunks and, inside, its children's
/// cuts along one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// The chunks `[lo, hi)` of the node.
    pub chunks: ChunkBox,
    /// The axis its children are cut along.
    pub axis: usize,
    /// The children's boundaries on that axis: child `i` spans
    /// `cuts[i] .. cuts[i + 1]` (a child may be empty).
    pub cuts: Vec<u64>,
    /// The children, as indices into [`Decomposition::nodes`]; empty for a
    /// leaf (one process's part).
    pub children: Vec<usize>,
}

/// The split of a level's chunks over `n` processes.
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition {
    /// Group size of each compositing round, first round first.
    pub rounds: Vec<usize>,
    /// The tree, root first.
    pub nodes: Vec<Node>,
    /// Each process's leaf in `nodes`.
    pub leaves: Vec<usize>,
    /// Each process's weight (chunks that may show).
    pub weights: Vec<u64>,
}

impl Decomposition {
    /// Splits the `counts` chunks (x, y, z) over `n` processes, balancing
    /// `weight(chunk)` (e.g. 1 for a chunk that may show, 0 for one that
    /// is transparent). The root is cut into the last round's group size,
    /// its children into the one before, and so on, so that the processes
    /// of a first-round group are siblings.
    pub fn new(counts: [u64; 3], n: usize, weight: &dyn Fn([u64; 3]) -> u64) -> Decomposition {
        let rounds = rounds(n);
        let mut d = Decomposition {
            rounds: rounds.clone(),
            nodes: Vec::new(),
            leaves: vec![0; n.max(1)],
            weights: vec![0; n.max(1)],
        };
        d.split(([0; 3], counts), &rounds, 0, weight);
        d
    }

    /// Adds the node for `chunks`, cut by the rounds `left` (the last one
    /// at this node), for the processes from `rank0` with stride 1 in the
    /// first round's digit. Returns the node's index.
    fn split(
        &mut self,
        chunks: ChunkBox,
        left: &[usize],
        rank0: usize,
        weight: &dyn Fn([u64; 3]) -> u64,
    ) -> usize {
        let id = self.nodes.len();
        let (lo, hi) = chunks;
        self.nodes.push(Node {
            chunks,
            axis: 0,
            cuts: Vec::new(),
            children: Vec::new(),
        });
        let Some((&k, inner)) = left.split_last() else {
            self.leaves[rank0] = id;
            self.weights[rank0] = boxes_weight(chunks, weight);
            return id;
        };
        // The axis with the most chunks (the longest in chunks).
        let axis = (0..3).max_by_key(|&a| (hi[a] - lo[a], a)).unwrap_or(0);
        let slices: Vec<u64> = (lo[axis]..hi[axis])
            .map(|s| {
                let mut b = chunks;
                b.0[axis] = s;
                b.1[axis] = s + 1;
                boxes_weight(b, weight)
            })
            .collect();
        let cuts = balanced_cuts(&slices, k, lo[axis]);
        // The processes below child j differ in the digit of this round,
        // whose stride is the product of the rounds before it.
        let stride: usize = inner.iter().product();
        let mut children = Vec::with_capacity(k);
        for j in 0..k {
            let mut b = chunks;
            b.0[axis] = cuts[j];
            b.1[axis] = cuts[j + 1];
            children.push(self.split(b, inner, rank0 + j * stride, weight));
        }
        let node = &mut self.nodes[id];
        node.axis = axis;
        node.cuts = cuts;
        node.children = children;
        id
    }

    /// Process `rank`'s chunks.
    pub fn part(&self, rank: usize) -> ChunkBox {
        self.nodes[self.leaves[rank]].chunks
    }

    /// The node whose children process `rank`'s group composites in round
    /// `r`, and `rank`'s child index there.
    fn group_node(&self, rank: usize, r: usize) -> (usize, usize) {
        // Walk down from the root: the root decides the last round.
        let mut node = 0;
        for round in (r..self.rounds.len()).rev() {
            let stride: usize = self.rounds[..round].iter().product();
            let digit = (rank / stride) % self.rounds[round];
            if round == r {
                return (node, digit);
            }
            node = self.nodes[node].children[digit];
        }
        (node, 0)
    }

    /// The order in which `node`'s children lie along every ray of `view`,
    /// nearest first. A ray meets the children in this order: on the cut
    /// axis its coordinate moves one way only, away from the eye.
    pub fn order(&self, node: usize, view: &View) -> Vec<usize> {
        let n = &self.nodes[node];
        let a = n.axis;
        let k = n.children.len();
        let mut idx: Vec<usize> = (0..k).collect();
        match *view {
            View::Eye(e) => {
                let key = |i: usize| {
                    let (b0, b1) = (n.cuts[i] as f32, n.cuts[i + 1] as f32);
                    if e[a] < b0 {
                        b0 - e[a]
                    } else if e[a] > b1 {
                        e[a] - b1
                    } else {
                        0.0
                    }
                };
                idx.sort_by(|&i, &j| key(i).total_cmp(&key(j)));
            }
            View::Direction(f) => {
                if f[a] < 0.0 {
                    idx.reverse();
                }
            }
        }
        idx
    }
}

/// The summed weight of the chunks in a box.
fn boxes_weight((lo, hi): ChunkBox, weight: &dyn Fn([u64; 3]) -> u64) -> u64 {
    let mut s = 0;
    for z in lo[2]..hi[2] {
        for y in lo[1]..hi[1] {
            for x in lo[0]..hi[0] {
                s += weight([x, y, z]);
            }
        }
    }
    s
}

/// `k + 1` boundaries (from `start`) that cut `slices` into `k` runs of
/// about equal weight, each at least one slice long where there are
/// enough; without any weight, runs of equal length.
fn balanced_cuts(slices: &[u64], k: usize, start: u64) -> Vec<u64> {
    let n = slices.len();
    let mut prefix = vec![0u64; n + 1];
    for (i, &w) in slices.iter().enumerate() {
        prefix[i + 1] = prefix[i] + w;
    }
    let total = prefix[n];
    let mut cuts = vec![0usize];
    for j in 1..k {
        let prev = cuts[j - 1];
        let (min_s, max_s) = if n >= k {
            (prev + 1, n - (k - j))
        } else {
            (prev, n)
        };
        let s = if total == 0 {
            n * j / k
        } else {
            // The first cut whose weight before it is nearest j/k of all.
            let target = total as f64 * j as f64 / k as f64;
            let off = |s: usize| (prefix[s] as f64 - target).abs();
            (min_s..=max_s)
                .min_by(|&a, &b| off(a).total_cmp(&off(b)))
                .unwrap_or(min_s)
        };
        cuts.push(s.clamp(min_s, max_s.max(min_s)));
    }
    cuts.push(n);
    cuts.into_iter().map(|c| start + c as u64).collect()
}

/// Where the rays come from, in the rendered level's chunk units (voxel
/// coordinates divided by the chunk shape): a perspective eye, or an
/// orthographic view direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum View {
    Eye(Vec3),
    Direction(Vec3),
}

impl View {
    /// The view of `cam` over `level`.
    pub fn new(cam: &Camera, level: &Level) -> View {
        let ch = Vec3::from(level.chunk.map(|c| c as f32));
        if cam.is_orthographic() {
            View::Direction(cam.forward / level.spacing / ch)
        } else {
            View::Eye((cam.eye - level.origin) / level.spacing / ch)
        }
    }
}

/// What compositing did on one process.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CompositeStats {
    /// Rounds of radix-k.
    pub rounds: usize,
    /// Bytes this process sent (the rounds and the final gather).
    pub bytes_sent: u64,
    /// Seconds from the first send to holding the result.
    pub seconds: f64,
}

/// The pixels `[a, b)` (flat, row by row) of piece `j` of `k` of `[lo, hi)`.
fn piece(lo: usize, hi: usize, j: usize, k: usize) -> (usize, usize) {
    (lo + (hi - lo) * j / k, lo + (hi - lo) * (j + 1) / k)
}

/// The pixel range process `rank` holds after every round, of `pixels`.
fn final_range(d: &Decomposition, rank: usize, pixels: usize) -> (usize, usize) {
    let (mut lo, mut hi) = (0, pixels);
    for (r, &k) in d.rounds.iter().enumerate() {
        let stride: usize = d.rounds[..r].iter().product();
        let j = (rank / stride) % k;
        (lo, hi) = piece(lo, hi, j, k);
    }
    (lo, hi)
}

/// Composites each process's premultiplied `partial` image (all the same
/// size) by radix-k over `ex`; process 0 gets the whole image, the others
/// `None`. Every process must call it with the same `d` and `view`.
pub fn composite(
    ex: &dyn Exchange,
    d: &Decomposition,
    view: &View,
    partial: Vec<[f32; 4]>,
) -> Result<(Option<Vec<[f32; 4]>>, CompositeStats)> {
    let start = Instant::now();
    let rank = ex.rank();
    if ex.size() != d.leaves.len() {
        return Err(Error::invalid(format!(
            "sort-last: {} processes, but the volume was split in {} parts",
            ex.size(),
            d.leaves.len()
        )));
    }
    let pixels = partial.len();
    let mut stats = CompositeStats {
        rounds: d.rounds.len(),
        ..Default::default()
    };
    // The piece of the image held (pixels `[lo, hi)`, four values each).
    let (mut lo, mut hi) = (0usize, pixels);
    let mut held: Vec<f32> = partial.into_flattened();
    for (r, &k) in d.rounds.iter().enumerate() {
        let stride: usize = d.rounds[..r].iter().product();
        let (node, me) = d.group_node(rank, r);
        let base = rank - me * stride;
        let peers: Vec<usize> = (0..k).map(|j| base + j * stride).collect();
        // Send piece j to member j, only its stretch from the first to the
        // last pixel that holds anything (the rest is transparent); keep
        // our own.
        let out: Vec<Vec<f32>> = (0..k)
            .map(|j| {
                if j == me {
                    return Vec::new();
                }
                let (a, b) = piece(lo, hi, j, k);
                let m = active(&held[4 * (a - lo)..4 * (b - lo)]);
                stats.bytes_sent += 4 * m.len() as u64;
                m
            })
            .collect();
        let got = ex.exchange(r as u32, &peers, out)?;
        let (a, b) = piece(lo, hi, me, k);
        let mine = &held[4 * (a - lo)..4 * (b - lo)];
        // Over, nearest child first: each layer under what is in front.
        let mut acc = vec![0.0f32; 4 * (b - a)];
        for child in d.order(node, view) {
            let (start, layer) = if child == me {
                (0, mine)
            } else {
                let m = &got[child];
                let stretch = (m.len() >= 2)
                    .then(|| (m[0].to_bits() as usize, &m[2..]))
                    .filter(|&(s, l)| {
                        l.len() == 4 * m[1].to_bits() as usize && 4 * s + l.len() <= acc.len()
                    });
                let Some(stretch) = stretch else {
                    return Err(Error::invalid(format!(
                        "sort-last: process {} sent a malformed piece in round {r} ({} values for {} pixels)",
                        peers[child],
                        m.len(),
                        b - a
                    )));
                };
                stretch
            };
            under(&mut acc[4 * start..4 * start + layer.len()], layer);
        }
        held = acc;
        (lo, hi) = (a, b);
    }
    debug_assert_eq!((lo, hi), final_range(d, rank, pixels));
    if rank != 0 {
        stats.bytes_sent += 4 * held.len() as u64;
    }
    let all = ex.gather(d.rounds.len() as u32, held)?;
    let image = all
        .map(|parts| {
            let mut img = vec![[0.0f32; 4]; pixels];
            for (p, data) in parts.iter().enumerate() {
                let (a, b) = final_range(d, p, pixels);
                if data.len() != 4 * (b - a) {
                    return Err(Error::invalid(format!(
                        "sort-last: process {p} sent {} values to gather, expected {}",
                        data.len(),
                        4 * (b - a)
                    )));
                }
                img[a..b].as_flattened_mut().copy_from_slice(data);
            }
            Ok(img)
        })
        .transpose()?;
    stats.seconds = start.elapsed().as_secs_f64();
    Ok((image, stats))
}

/// `back` composited under `front` (premultiplied RGBA, four values a
/// pixel: `front` over `back`), in place of `front`.
fn under(front: &mut [f32], back: &[f32]) {
    for (f, b) in front.chunks_exact_mut(4).zip(back.chunks_exact(4)) {
        let t = 1.0 - f[3];
        for c in 0..4 {
            f[c] += t * b[c];
        }
    }
}

/// The message for a piece of premultiplied pixels: the stretch from its
/// first to its last pixel that is not fully transparent, as the stretch's
/// first pixel and pixel count (their bits as two `f32`s), then its values.
/// A piece outside a part's screen footprint costs two values — the
/// active-pixel bounds of IceT, in one dimension.
fn active(piece: &[f32]) -> Vec<f32> {
    let used = |p: &[f32]| p.iter().any(|&v| v != 0.0);
    let first = piece
        .chunks_exact(4)
        .position(used)
        .unwrap_or(piece.len() / 4);
    let last = piece
        .chunks_exact(4)
        .rposition(used)
        .map_or(first, |i| i + 1);
    let mut m = Vec::with_capacity(2 + 4 * (last - first));
    m.push(f32::from_bits(first as u32));
    m.push(f32::from_bits((last - first) as u32));
    m.extend_from_slice(&piece[4 * first..4 * last]);
    m
}

/// One process's figures of a sort-last render.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SortLastStats {
    /// This process's rank and the number of processes.
    pub rank: usize,
    pub ranks: usize,
    /// Its part: chunks `[lo, hi)` of the rendered level, and how many of
    /// them may show.
    pub part: ChunkBox,
    pub weight: u64,
    /// Seconds rendering its part.
    pub render_seconds: f64,
    /// Seconds waiting, after its render, for every process to finish
    /// theirs (load imbalance).
    pub wait_seconds: f64,
    pub composite: CompositeStats,
    pub out_of_core: OutOfCoreStats,
}

/// The hue process `rank`'s part is tinted with (`show_parts`): Tableau's
/// ten colours, linear RGB, repeating.
pub fn part_colour(rank: usize) -> [f32; 3] {
    const TAB10: [[u8; 3]; 10] = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [127, 127, 127],
        [188, 189, 34],
        [23, 190, 207],
    ];
    TAB10[rank % 10].map(|v| crate::transfer::srgb_to_linear(v as f32 / 255.0))
}

/// What a sort-last render gives each process.
pub struct SortLast {
    /// The picture, on process 0 only.
    pub image: Option<Image>,
    /// This process's counts (its part's samples).
    pub stats: RenderStats,
    pub sort_last: SortLastStats,
}

/// Checks that a sort-last render can run `params`; the error names the
/// setting and the reason.
pub fn check_params(params: &RenderParams) -> Result<()> {
    outofcore::check_uniform(
        params,
        "a sort-last (MPI) render",
        "adaptive steps, grouped reuse, level-of-detail and stochastic marchers decide along the whole ray, which no process holds",
    )
}

/// Renders `source` split over the processes of `ex` and composites the
/// parts: process 0 gets the image. Every process must call it with the
/// same arguments. Early ray termination is switched off (see the module
/// documentation), so the picture is the one-process render's with
/// `ert = 1`. With `show_parts`, each process's colours are tinted with its
/// own hue ([`part_colour`]), to see the split.
#[allow(clippy::too_many_arguments)]
pub fn render(
    ex: &dyn Exchange,
    ooc: &OutOfCore<'_>,
    tf: &TransferFunction,
    window: [f32; 2],
    camera: &CameraParams,
    params: &RenderParams,
    show_parts: bool,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
) -> Result<SortLast> {
    check_params(params)?;
    let mut params = params.clone();
    params.ert = 1.0;
    let source = ooc.source();
    let levels = source.levels();
    if levels.is_empty() {
        return Err(Error::invalid(format!(
            "{}: the store has no levels",
            source.name()
        )));
    }
    let (lo, hi) = outofcore::world_bounds(levels);
    let cam = Camera::fit(camera, lo, hi, params.width, params.height);
    let lidx = ooc.level_for(&cam)?;
    let level = &levels[lidx];
    // Weigh each chunk by whether it may show: its brick reads the chunks
    // around it, so a transparent chunk beside a visible one still marches
    // its border; counting the chunk itself is near enough for balance.
    let w = outofcore::widen(window);
    let ranges = ooc.ranges(lidx);
    let weight = |c: [u64; 3]| {
        u64::from(!outofcore::known_empty(
            tf,
            w,
            &ranges[level.chunk_index(c)],
        ))
    };
    let d = Decomposition::new(level.chunk_counts(), ex.size(), &weight);
    let rank = ex.rank();
    let part = d.part(rank);
    let t = Instant::now();
    let (mut pixels, stats, oo) =
        ooc.render_part(tf, window, camera, &params, Some(part), progress, cancel)?;
    if show_parts {
        let t = part_colour(rank);
        for p in &mut pixels {
            // The part's brightness in its hue (premultiplied: opacity kept).
            let y = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
            for c in 0..3 {
                p[c] = (0.35 * p[3] + 0.65 * y) * t[c];
            }
        }
    }
    let render_seconds = t.elapsed().as_secs_f64();
    let view = View::new(&cam, level);
    let t = Instant::now();
    ex.barrier()?;
    let wait_seconds = t.elapsed().as_secs_f64();
    let (image, cs) = composite(ex, &d, &view, pixels)?;
    let image = image
        .map(|p| outofcore::with_background(p, params.width, params.height, params.background));
    Ok(SortLast {
        image,
        stats,
        sort_last: SortLastStats {
            rank,
            ranks: ex.size(),
            part,
            weight: d.weights[rank],
            render_seconds,
            wait_seconds,
            composite: cs,
            out_of_core: oo,
        },
    })
}
