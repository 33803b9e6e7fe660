//! The BVH shadow rays traverse: the triangles that cast shadows only (objects whose role has
//! `occluder`), so a receiver-only object (a room's walls, a ground plane) costs a shadow ray
//! nothing; the eye pass keeps its own BVH of every object ([`super::bvh::SceneBvh`]).
//!
//! **Answers.** A shadow ray from `o` along the unit direction `d` with length `len` is blocked
//! when a casting triangle's plane lies at `t ∈ [0, len)` and the line crosses the triangle by
//! the one coverage rule ([`coverage::line_crosses`]: exact on shared edges and vertices). That
//! is decided by the triangle tests alone, never by the tree: child boxes hold their triangles
//! with a margin (`bvh::tie_breaking_box`, 2⁻¹⁹ of the scene or more, about 16 `f32` steps at
//! the scene's scale) far above the rounding of a box test, so a box that holds a crossing is
//! never missed whatever the instruction set or the order of the arithmetic. The triangle test
//! itself is scalar IEEE arithmetic in one fixed order (no fused multiply-add), so every
//! instruction set gives the same bits.
//!
//! **Instruction sets.** The child-box test of the compressed 8-wide nodes (Ylitie, Karras and
//! Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017;
//! obvhs's layout) is written three times: all eight children in one AVX2 vector with FMA, four
//! at a time in SSE2 (every x86-64), and one at a time elsewhere. [`Isa::host`] picks the widest
//! the CPU runs, detected at run time (`is_x86_feature_detected!`), so the portable binary
//! traverses at the host's width; the traversal loop and the triangle test are compiled into
//! each variant (`#[target_feature]`).
//!
//! **Coherent rays.** The reference's rays come in groups from one shading point towards one
//! light. [`ShadowBvh::gather`] traverses the tree once with the cone from the point around the
//! light's bounding sphere and collects the casting triangles in it (up to a cap); every ray of
//! the group then tests only those ([`ShadowBvh::occluded_among`]), and a group with none is
//! answered without a ray. A triangle a ray of the group crosses lies in that cone, so the
//! answers are the same as one ray at a time (the cone test is conservative: margins of 10⁻⁵ of
//! the scene over the rounding of its arithmetic).
//!
//! **Shared origin.** The rays of a group share their origin, so what the triangle test computes
//! of the origin alone (the plane's numerator, each edge's cross product) is computed once per
//! caster and group ([`Facing`]): the same operations on the same values, the same bits. The
//! reference's default tracer traces a group with more casters than the cap as packets
//! ([`ShadowBvh::occluded_packet`]): one traversal for up to [`PACKET`] rays, each node fetched
//! once for the rays that reach it, the blocker of the previous packet (the same pixel's or,
//! mostly, a neighbouring one's) tested on every ray first.

use std::sync::OnceLock;
use std::time::Duration;

use glam::{UVec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use super::mesh::FlatMesh;
use super::{bvh, coverage};

/// Depth-first traversal of a `CwBvh` (obvhs's `traverse!` loop: children in the order of the
/// direction's octant) with the child-box test `$test` (a hit mask in obvhs's layout), until
/// `$stop` holds for a primitive: `Some(its leaf index)`, or `None` when none stopped it.
macro_rules! traverse_until {
    ($bvh:expr, $dir:expr, $node:ident => $test:expr, $prim:ident => $stop:expr) => {{
        let bvh: &CwBvh = $bvh;
        let mut state = bvh.new_traversal($dir);
        let mut current;
        let mut found: Option<u32> = None;
        'traversal: {
            obvhs::traverse!(
                bvh,
                current,
                state,
                {
                    let $node: &CwBvhNode = current;
                    $test
                },
                {
                    let $prim = state.primitive_id as usize;
                    if $stop {
                        found = Some(state.primitive_id);
                        break 'traversal;
                    }
                }
            );
        }
        found
    }};
}

/// The masked packet traversal of [`ShadowBvh::occluded_packet`] with the per-ray child-box
/// test `$children` (bit `j`: the ray meets child slot `j`); the mask of blocked rays.
macro_rules! packet_until {
    ($shadow:expr, $rays:expr, $stack:expr, $children:path) => {{
        let shadow: &ShadowBvh = $shadow;
        let rays: &[ShadowRay] = $rays;
        let stack: &mut PacketStack = $stack;
        let nodes = &shadow.bvh.nodes;
        let mut active: u64 = if rays.len() == PACKET {
            u64::MAX
        } else {
            (1u64 << rays.len()) - 1
        };
        let mut blocked = 0u64;
        let origin = rays.first().map_or(Vec3::ZERO, |r| r.s.o);
        assert!(
            rays.iter().all(|r| r.s.o == origin),
            "the rays of a packet start at one point"
        );
        // Children in the order of the first ray's octant, nearest popped first (obvhs's order).
        let oct = rays.first().map_or(0, |r| (r.oct_inv4 & 7) as usize);
        // The caster that blocked a ray of the previous packet first, on every ray.
        if let Some(h) = stack.hint.filter(|&h| (h as usize) < shadow.casters.len()) {
            let caster = shadow.casters[h as usize].facing(origin);
            block_with(&caster, rays, &mut active, &mut blocked);
        }
        stack.nodes.clear();
        if !nodes.is_empty() && active != 0 {
            stack.nodes.push((0, active));
        }
        while let Some((index, reached)) = stack.nodes.pop() {
            let reached = reached & active;
            if reached == 0 {
                continue;
            }
            let node = &nodes[index as usize];
            // Per child slot, the rays that meet its box.
            let mut child = [0u64; 8];
            let mut m = reached;
            while m != 0 {
                let r = m.trailing_zeros() as usize;
                m &= m - 1;
                let mut c = $children(node, &rays[r]);
                while c != 0 {
                    child[c.trailing_zeros() as usize] |= 1 << r;
                    c &= c - 1;
                }
            }
            let imask = u32::from(node.imask);
            for (j, &meta) in node.child_meta.iter().enumerate() {
                if imask >> j & 1 == 1 || child[j] & active == 0 {
                    continue;
                }
                // A leaf: the low 5 bits its first primitive's offset, the high 3 its count in
                // unary.
                let first = node.primitive_base_idx + u32::from(meta & 0x1f);
                for prim in first..first + (meta >> 5).count_ones() {
                    let mut m = child[j] & active;
                    if m == 0 {
                        break;
                    }
                    let caster = shadow.casters[prim as usize].facing(origin);
                    while m != 0 {
                        let r = m.trailing_zeros();
                        m &= m - 1;
                        if caster.blocks(rays[r as usize].s.d, rays[r as usize].s.len) {
                            active &= !(1 << r);
                            blocked |= 1 << r;
                            stack.hint = Some(prim);
                            // Every other ray still in the packet (the rest of `m` among them).
                            block_with(&caster, rays, &mut active, &mut blocked);
                            break;
                        }
                    }
                }
            }
            if active == 0 {
                break;
            }
            for step in 0..8 {
                let j = step ^ oct;
                if imask >> j & 1 == 1 && child[j] & active != 0 {
                    let below = (imask & ((1 << j) - 1)).count_ones();
                    stack.nodes.push((node.child_base_idx + below, child[j]));
                }
            }
        }
        blocked
    }};
}

/// Tests `caster` on every ray of `active` (bit `r`: `rays[r]`), moving those it blocks from
/// `active` to `blocked`. A function, not a closure: a closure is not always inlined into the
/// traversal.
#[inline(always)]
fn block_with(caster: &Facing, rays: &[ShadowRay], active: &mut u64, blocked: &mut u64) {
    let mut m = *active;
    while m != 0 {
        let r = m.trailing_zeros();
        m &= m - 1;
        let s = &rays[r as usize].s;
        if caster.blocks(s.d, s.len) {
            *active &= !(1 << r);
            *blocked |= 1 << r;
        }
    }
}

/// The most rays [`ShadowBvh::occluded_packet`] traces together (one bit each of a `u64`).
pub const PACKET: usize = 64;

/// The node stack of [`ShadowBvh::occluded_packet`] (a node and the rays that reached it),
/// kept between packets so that none allocates, and the caster that last blocked a ray (tested
/// first on the next packet, mostly the same or a neighbouring pixel's: the same answers, found
/// sooner in an umbra). Reused with another tree, the hint is only a caster of that tree (or
/// none, beyond its casters), so the answers stay the same.
#[derive(Debug, Default)]
pub struct PacketStack {
    nodes: Vec<(u32, u64)>,
    hint: Option<u32>,
}

/// The instruction set the traversal runs on ([`Isa::host`]: chosen at run time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// The eight children of a node in one 256-bit vector: AVX2 with FMA (x86-64-v3).
    Avx2,
    /// Four children at a time: SSE2 (every x86-64 CPU; the portable build's baseline).
    Sse2,
    /// One child at a time (other architectures).
    Scalar,
}

impl Isa {
    /// The widest instruction set this CPU runs, detected once.
    pub fn host() -> Isa {
        static HOST: OnceLock<Isa> = OnceLock::new();
        *HOST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                    && std::arch::is_x86_feature_detected!("bmi1")
                    && std::arch::is_x86_feature_detected!("bmi2")
                    && std::arch::is_x86_feature_detected!("lzcnt")
                    && std::arch::is_x86_feature_detected!("popcnt")
                {
                    Isa::Avx2
                } else {
                    Isa::Sse2
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                Isa::Scalar
            }
        })
    }

    /// The instruction sets this CPU runs, widest first (the host's, then the narrower ones).
    pub fn available() -> Vec<Isa> {
        [Isa::Avx2, Isa::Sse2, Isa::Scalar]
            .into_iter()
            .skip_while(|&i| i != Isa::host())
            .collect()
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx2 => "avx2",
            Isa::Sse2 => "sse2",
            Isa::Scalar => "scalar",
        }
    }
}

/// A casting triangle in the BVH's local coordinates, with what its test needs computed once:
/// the (unnormalised) normal `(b − a) × (c − a)` and, per directed edge `v[k] → v[k + 1]`,
/// whether its end precedes its start lexicographically (the coverage rule then evaluates it
/// from the end, [`coverage::edge_plane`]).
#[derive(Clone, Copy, Debug)]
struct Caster {
    v: [Vec3; 3],
    n: Vec3,
    from_end: [bool; 3],
}

impl Caster {
    fn new(a: Vec3, b: Vec3, c: Vec3) -> Caster {
        let v = [a, b, c];
        Caster {
            v,
            n: (b - a).cross(c - a),
            from_end: std::array::from_fn(|k| coverage::precedes(v[(k + 1) % 3], v[k])),
        }
    }

    /// Whether the triangle blocks the segment: its plane at `t ∈ [0, len)` and the line
    /// through it by the coverage rule. The same operations on the same values as
    /// [`coverage::line_crosses`] with the edges `(a, b), (b, c), (c, a)`, so the same bits.
    #[inline(always)]
    fn blocks(&self, s: &Segment) -> bool {
        let nd = self.n.dot(s.d);
        if nd == 0.0 {
            return false;
        }
        // The plane's distance first: most candidates are rejected by it, before the three
        // edge functions of the coverage rule.
        let t = self.n.dot(self.v[0] - s.o) / nd;
        if !(t >= 0.0 && t < s.len) {
            return false;
        }
        let rel = self.v.map(|p| p - s.o);
        // The three edges written out: an iterator's `all` or a closure is not always inlined
        // into the traversal (a call per test).
        self.covers(0, &rel, s.d, nd)
            && self.covers(1, &rel, s.d, nd)
            && self.covers(2, &rel, s.d, nd)
    }

    /// Whether the line along `d` lies on the inner side of edge `k` (`rel`: the vertices
    /// relative to the segment's origin; `nd`: `n · d`, not 0).
    #[inline(always)]
    fn covers(&self, k: usize, rel: &[Vec3; 3], d: Vec3, nd: f32) -> bool {
        let (p, q) = (rel[k], rel[(k + 1) % 3]);
        // The edge function of v[k] → v[k + 1] ([`coverage::edge_function`]); the reversed
        // edge's, which a back-facing line tests, is its exact negation.
        let forward = if self.from_end[k] {
            -d.dot(q.cross(p))
        } else {
            d.dot(p.cross(q))
        };
        inner_side(forward, nd, d, self.v[k], self.v[(k + 1) % 3])
    }
}

/// A casting triangle seen from one origin `o`: what [`Caster::blocks`] computes of `o` alone
/// (the plane's numerator `n · (v₀ − o)` and each edge's `(vₖ − o) × (vₖ₊₁ − o)`, the sign of
/// the coverage rule's evaluation order folded in) done once for every segment from `o` (a
/// pixel's shadow rays share their shading point), with the same operations on the same values,
/// so the same answers to the bit.
#[derive(Clone, Copy, Debug)]
pub struct Facing {
    n: Vec3,
    /// `n · (v₀ − o)`.
    num: f32,
    /// Per edge `vₖ → vₖ₊₁`, the vector whose dot product with a direction is its edge function.
    edge: [Vec3; 3],
    v: [Vec3; 3],
}

impl Caster {
    /// The triangle seen from `o` ([`Facing`]).
    #[inline(always)]
    fn facing(&self, o: Vec3) -> Facing {
        let rel = self.v.map(|p| p - o);
        Facing {
            n: self.n,
            num: self.n.dot(self.v[0] - o),
            edge: std::array::from_fn(|k| {
                let (p, q) = (rel[k], rel[(k + 1) % 3]);
                // −(d · (q × p)) is d · −(q × p) to the bit (negation is exact, and the
                // comparisons below do not tell −0 from +0).
                if self.from_end[k] {
                    -q.cross(p)
                } else {
                    p.cross(q)
                }
            }),
            v: self.v,
        }
    }
}

impl Facing {
    /// [`Caster::blocks`] of the segment from this facing's origin along the unit `d` with
    /// length `len`.
    #[inline(always)]
    fn blocks(&self, d: Vec3, len: f32) -> bool {
        let nd = self.n.dot(d);
        if nd == 0.0 {
            return false;
        }
        let t = self.num / nd;
        if !(t >= 0.0 && t < len) {
            return false;
        }
        // The three edges written out: an iterator's `all` or a closure is not always inlined
        // into the traversal (a call per test).
        self.covers(0, d, nd) && self.covers(1, d, nd) && self.covers(2, d, nd)
    }

    /// Whether the line along `d` lies on the inner side of edge `k` (`nd`: `n · d`, not 0).
    #[inline(always)]
    fn covers(&self, k: usize, d: Vec3, nd: f32) -> bool {
        inner_side(d.dot(self.edge[k]), nd, d, self.v[k], self.v[(k + 1) % 3])
    }
}

/// Whether a line along `d` whose edge function of the directed edge `a → b` is `forward` lies
/// on the triangle's inner side of it, the triangle seen from the side `nd = n · d` (not 0)
/// says: the edge function itself when front-facing, its exact negation when back-facing (the
/// reversed edge `b → a`), ties broken by [`coverage::tie_owner`].
#[inline(always)]
fn inner_side(forward: f32, nd: f32, d: Vec3, a: Vec3, b: Vec3) -> bool {
    if nd > 0.0 {
        forward > 0.0 || (forward == 0.0 && coverage::tie_owner(d, a, b))
    } else {
        forward < 0.0 || (forward == 0.0 && coverage::tie_owner(d, b, a))
    }
}

/// A shadow ray's segment in local coordinates: origin, unit direction and length.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    o: Vec3,
    d: Vec3,
    len: f32,
}

impl Segment {
    /// The segment from `o` to `to` (local coordinates), or `None` when it has no length.
    #[inline(always)]
    fn new(o: Vec3, to: Vec3) -> Option<Segment> {
        let v = to - o;
        let len = v.length();
        (len > 0.0).then(|| Segment { o, d: v / len, len })
    }

    /// The origin, unit direction and length (local coordinates): what an outside ray tracer
    /// is given to trace the same ray.
    pub fn parts(&self) -> (Vec3, Vec3, f32) {
        (self.o, self.d, self.len)
    }
}

/// A shadow ray set up for the traversal's box tests.
#[derive(Clone, Copy, Debug)]
pub struct ShadowRay {
    s: Segment,
    /// obvhs's ray: origin, direction and the safe reciprocal of the direction.
    ray: Ray,
    /// The traversal order's octant code (obvhs's `oct_inv4`).
    oct_inv4: u32,
    /// Per axis, whether the direction is negative (the box slab is entered at its max).
    neg: [bool; 3],
}

impl ShadowRay {
    #[inline(always)]
    fn new(s: Segment) -> ShadowRay {
        let d = s.d;
        ShadowRay {
            s,
            ray: Ray::new(Vec3A::from(s.o), Vec3A::from(d), 0.0, s.len),
            oct_inv4: octant(d),
            neg: [d.x < 0.0, d.y < 0.0, d.z < 0.0],
        }
    }
}

/// The cone from a shading point around a light's bounding sphere (local coordinates), with
/// its reach: every segment from the point to a point of the sphere lies inside.
#[derive(Clone, Copy, Debug)]
struct Cone {
    apex: Vec3,
    axis: Vec3,
    sin: f32,
    cos: f32,
    reach: f32,
    /// Margin over the rounding of the test and of the rays' directions (which stray from the
    /// exact segment by an `f32` step of their length).
    slack: f32,
}

/// Absolute margin of the cone test, local units (the scene's diagonal is in [1, 2)): far above
/// the rounding of its arithmetic (a few 10⁻⁷ at the scene's scale).
const CONE_MARGIN: f32 = 1e-5;

impl Cone {
    /// Whether the child box `[lo, hi]` may hold a point of the cone within its reach
    /// (conservative: the box's bounding sphere against the cone, with margins).
    #[inline(always)]
    fn may_meet(&self, lo: Vec3, hi: Vec3) -> bool {
        let centre = (lo + hi) * 0.5;
        let rho = (hi - lo).length() * 0.5 + self.slack;
        let v = centre - self.apex;
        let dist = v.length();
        if dist - rho > self.reach {
            return false;
        }
        if dist <= rho {
            return true;
        }
        // Distance from the sphere's centre to the cone's surface, in the plane of the axis
        // and the centre: at most the radius when they meet.
        let along = v.dot(self.axis);
        let across = v.cross(self.axis).length();
        across * self.cos - along * self.sin <= rho
    }
}

/// What [`ShadowBvh::gather`] found in a cone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gathered {
    /// No casting triangle: every ray of the group reaches the light.
    Empty,
    /// The casting triangles the group's rays may meet, in the candidate list.
    Few,
    /// More than the cap, or no cone bounds the group (the point inside the light's sphere):
    /// trace the rays one at a time.
    Many,
}

/// The shadow rays' BVH: the casting triangles of a scene in the local coordinates of the
/// scene's BVH (`(p − origin) · scale`, the same bits as the eye pass's BVH), in leaf order.
pub struct ShadowBvh {
    bvh: CwBvh,
    casters: Vec<Caster>,
    origin: Vec3,
    scale: f32,
}

/// The build quality of [`ShadowBvh`] (obvhs's PLOC presets). `fast_build` traverses the
/// reference's rays as fast as `medium_build` within a few per cent and builds in about half
/// the time (docs/algorithms.md, "The reference's speed").
pub const BUILD: BvhBuildParams = BvhBuildParams::medium_build();

impl ShadowBvh {
    /// The BVH of the casting triangles of `flat` (objects whose role has `occluder`), in the
    /// local coordinates of the scene's BVH ([`super::bvh::SceneBvh`]), each box widened as the
    /// scene's are (`bvh::tie_breaking_box`, by the triangle's index in the flat mesh).
    pub fn of_scene(flat: &FlatMesh) -> ShadowBvh {
        let (origin, scale) = bvh::local_frame(flat);
        let local = |p: Vec3| (p - origin) * scale;
        let index: Vec<u32> = (0..flat.mesh.triangles.len() as u32)
            .filter(|&t| flat.role_of(t as usize).occluder)
            .collect();
        let triangles: Vec<[Vec3; 3]> = index
            .iter()
            .map(|&t| flat.mesh.triangle(t as usize).map(local))
            .collect();
        let bvh = if triangles.is_empty() {
            CwBvh::default()
        } else {
            let boxes: Vec<Aabb> = index
                .iter()
                .zip(&triangles)
                .map(|(&t, &[a, b, c])| {
                    let tri = Triangle {
                        v0: a.into(),
                        v1: b.into(),
                        v2: c.into(),
                    };
                    bvh::tie_breaking_box(&tri, t as usize)
                })
                .collect();
            obvhs::cwbvh::builder::build_cwbvh(&boxes, BUILD, &mut Duration::default())
        };
        let order = &bvh.primitive_indices;
        let casters = order
            .iter()
            .map(|&i| {
                let [a, b, c] = triangles[i as usize];
                Caster::new(a, b, c)
            })
            .collect();
        ShadowBvh {
            bvh,
            casters,
            origin,
            scale,
        }
    }

    /// Number of casting triangles.
    pub fn len(&self) -> usize {
        self.casters.len()
    }

    pub fn is_empty(&self) -> bool {
        self.casters.is_empty()
    }

    /// The casting triangles in local coordinates (leaf order), what an outside ray tracer is
    /// given to trace [`ShadowRay::parts`].
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.casters.iter().map(|c| c.v)
    }

    /// `p` in local coordinates.
    #[inline(always)]
    pub fn local(&self, p: Vec3) -> Vec3 {
        (p - self.origin) * self.scale
    }

    /// The segment from `from` to `to` (world coordinates) in local coordinates, or `None`
    /// when it has no length there (nothing blocks it).
    #[inline(always)]
    pub fn segment(&self, from: Vec3, to: Vec3) -> Option<Segment> {
        Segment::new(self.local(from), self.local(to))
    }

    /// The shadow ray from `from` to `to` (world coordinates) set up for traversal, or `None`
    /// as [`Self::segment`].
    #[inline(always)]
    pub fn ray(&self, from: Vec3, to: Vec3) -> Option<ShadowRay> {
        self.segment(from, to).map(ShadowRay::new)
    }

    /// Whether a casting triangle blocks the open segment from `from` to `to` (world
    /// coordinates), traversed on the host's instruction set.
    pub fn occluded(&self, from: Vec3, to: Vec3) -> bool {
        self.ray(from, to)
            .is_some_and(|r| self.occluded_ray(Isa::host(), &r, &mut None))
    }

    /// Whether a casting triangle blocks `ray`, traversed on `isa` (which must be one of
    /// [`Isa::available`]). `hint`: a caster that blocked a neighbouring ray, tested first and
    /// replaced by this ray's blocker (the same answer, found sooner in an umbra).
    ///
    /// # Panics
    /// If `isa` is not one this CPU runs.
    #[inline]
    pub fn occluded_ray(&self, isa: Isa, ray: &ShadowRay, hint: &mut Option<u32>) -> bool {
        if let Some(h) = *hint {
            if self.casters[h as usize].blocks(&ray.s) {
                return true;
            }
        }
        let blocker = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                assert!(
                    Isa::host() == Isa::Avx2,
                    "AVX2 is not available on this CPU"
                );
                // SAFETY: the CPU runs AVX2, FMA, BMI1/2, LZCNT and POPCNT (`Isa::host`).
                unsafe { self.first_blocker_avx2(ray) }
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: every x86-64 CPU runs SSE2.
            Isa::Sse2 => unsafe { self.first_blocker_sse2(ray) },
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 | Isa::Sse2 => panic!("{} is not available on this CPU", isa.name()),
            Isa::Scalar => self.first_blocker_scalar(ray),
        };
        if blocker.is_some() {
            *hint = blocker;
        }
        blocker.is_some()
    }

    /// Whether a casting triangle blocks `ray`, by obvhs's own traversal of this tree
    /// (`CwBvh::ray_traverse_miss`: its SSE child-box test, which also skips boxes nearer than
    /// 10⁻⁴ along the ray) with the same triangle test: the baseline that tells the casters'
    /// tree's gain from the traversal's.
    pub fn occluded_obvhs(&self, ray: &ShadowRay) -> bool {
        !self.bvh.ray_traverse_miss(ray.ray, |_, id| {
            if self.casters[id].blocks(&ray.s) {
                0.0
            } else {
                f32::INFINITY
            }
        })
    }

    /// Collects into `out` (cleared first) the casting triangles that a segment from `from` to a
    /// point of the sphere around `centre` with `radius` (world coordinates) may cross, at most
    /// `cap` of them.
    pub fn gather(
        &self,
        isa: Isa,
        from: Vec3,
        centre: Vec3,
        radius: f32,
        cap: usize,
        out: &mut Vec<u32>,
    ) -> Gathered {
        self.gather_between(isa, (from, 0.0), (centre, radius), cap, out)
    }

    /// [`Self::gather`] for segments from any point of the ball `from` (centre, radius) to any
    /// point of the ball `to` (world coordinates): the casters in the cone tangent to both
    /// (a tile of shading points and the light). [`Gathered::Many`] also where the first ball
    /// is not well inside the second's cone (not smaller than it, or overlapping it).
    pub fn gather_between(
        &self,
        isa: Isa,
        (from, from_radius): (Vec3, f32),
        (centre, radius): (Vec3, f32),
        cap: usize,
        out: &mut Vec<u32>,
    ) -> Gathered {
        out.clear();
        let near = self.local(from);
        let c = self.local(centre);
        // Both spheres grown over the rounding of the points in them (world coordinates, about
        // an `f32` step of their magnitude) and of their local coordinates.
        let magnitude =
            centre.abs().max_element() + from.abs().max_element() + radius + from_radius;
        let rounding = 8.0 * f32::EPSILON * magnitude;
        let r = (radius * (1.0 + 1e-4) + rounding) * self.scale + CONE_MARGIN;
        let rp = if from_radius > 0.0 {
            (from_radius * (1.0 + 1e-4) + rounding) * self.scale + CONE_MARGIN
        } else {
            0.0
        };
        let v = c - near;
        let dist = v.length();
        if !dist.is_finite() || dist <= (r + rp) * 1.01 || rp >= 0.9 * r {
            return Gathered::Many;
        }
        let axis = v / dist;
        // The tangent cone's apex lies behind the smaller ball, where the radii extrapolate
        // to zero.
        let back = dist * rp / (r - rp);
        let sin = ((r - rp) / dist) * (1.0 + 1e-5);
        let reach = back + dist + r + CONE_MARGIN;
        let cone = Cone {
            apex: near - axis * back,
            axis,
            sin,
            cos: (1.0 - sin * sin).max(0.0).sqrt() * (1.0 - 1e-5),
            reach,
            slack: CONE_MARGIN + 1e-6 * reach,
        };
        let overflow = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                assert!(
                    Isa::host() == Isa::Avx2,
                    "AVX2 is not available on this CPU"
                );
                // SAFETY: the CPU runs AVX2 and the rest of x86-64-v3 (`Isa::host`).
                unsafe { self.gather_avx2(&cone, cap, out) }
            }
            _ => self.gather_portable(&cone, cap, out),
        };
        if overflow {
            Gathered::Many
        } else if out.is_empty() {
            Gathered::Empty
        } else {
            Gathered::Few
        }
    }

    /// `candidates` (from [`Self::gather`] of a group from `from`, world coordinates) seen from
    /// `from` ([`Facing`]), into `out` (cleared first), for [`Self::occluded_among`].
    pub fn facing_among(&self, candidates: &[u32], from: Vec3, out: &mut Vec<Facing>) {
        let o = self.local(from);
        out.clear();
        out.extend(
            candidates
                .iter()
                .map(|&c| self.casters[c as usize].facing(o)),
        );
    }

    /// Whether one of `facing` (from [`Self::facing_among`] of this segment's origin) blocks
    /// `segment`. The blocker found is moved to the front, where the group's next ray tests it
    /// first.
    #[inline(always)]
    pub fn occluded_among(facing: &mut [Facing], segment: &Segment) -> bool {
        match facing.iter().position(|c| c.blocks(segment.d, segment.len)) {
            Some(j) => {
                facing.swap(0, j);
                true
            }
            None => false,
        }
    }

    /// Which of `rays` (at most [`PACKET`] from one point, one bit each: bit `r` for `rays[r]`)
    /// a casting triangle blocks, traced together on `isa` (one of [`Isa::available`]): a masked packet
    /// traversal (Wald, Slusallek, Benthin and Wagner, "Interactive Rendering with Coherent Ray
    /// Tracing", Eurographics 2001), each node fetched once for the rays that reached it, each
    /// ray's child-box test the one of [`Self::occluded_ray`], a ray leaving the packet when
    /// blocked; a triangle that blocks one ray is tested next on every ray still in the packet
    /// (in an umbra it blocks them all), and so is the previous packet's first blocker. The
    /// answers are those of one ray at a time: a ray is blocked exactly when a casting triangle
    /// blocks it, and every such triangle lies in a leaf its box tests reach (the boxes hold
    /// their triangles with margins, `bvh::tie_breaking_box`), whichever test finds it.
    ///
    /// # Panics
    /// If `rays` holds more than [`PACKET`] rays or rays from different points, or `isa` is not
    /// one this CPU runs.
    pub fn occluded_packet(&self, isa: Isa, rays: &[ShadowRay], stack: &mut PacketStack) -> u64 {
        assert!(rays.len() <= PACKET, "{} rays in a packet", rays.len());
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                assert!(
                    Isa::host() == Isa::Avx2,
                    "AVX2 is not available on this CPU"
                );
                // SAFETY: the CPU runs AVX2, FMA, BMI1/2, LZCNT and POPCNT (`Isa::host`).
                unsafe { self.packet_avx2(rays, stack) }
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: every x86-64 CPU runs SSE2.
            Isa::Sse2 => unsafe { self.packet_sse2(rays, stack) },
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 | Isa::Sse2 => panic!("{} is not available on this CPU", isa.name()),
            Isa::Scalar => packet_until!(self, rays, stack, children_scalar),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    fn packet_sse2(&self, rays: &[ShadowRay], stack: &mut PacketStack) -> u64 {
        packet_until!(self, rays, stack, children_sse2)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn packet_avx2(&self, rays: &[ShadowRay], stack: &mut PacketStack) -> u64 {
        packet_until!(self, rays, stack, children_avx2)
    }

    fn gather_portable(&self, cone: &Cone, cap: usize, out: &mut Vec<u32>) -> bool {
        traverse_until!(
            &self.bvh,
            Vec3A::from(cone.axis),
            node => cone_hits(node, cone, octant(cone.axis)),
            prim => push_capped(out, prim, cap)
        )
        .is_some()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn gather_avx2(&self, cone: &Cone, cap: usize, out: &mut Vec<u32>) -> bool {
        traverse_until!(
            &self.bvh,
            Vec3A::from(cone.axis),
            node => cone_hits_avx2(node, cone, octant(cone.axis)),
            prim => push_capped(out, prim, cap)
        )
        .is_some()
    }

    fn first_blocker_scalar(&self, ray: &ShadowRay) -> Option<u32> {
        traverse_until!(
            &self.bvh,
            ray.ray.direction,
            node => hit_mask(node, children_scalar(node, ray), ray.oct_inv4),
            prim => self.casters[prim].blocks(&ray.s)
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    fn first_blocker_sse2(&self, ray: &ShadowRay) -> Option<u32> {
        traverse_until!(
            &self.bvh,
            ray.ray.direction,
            node => hit_mask(node, children_sse2(node, ray), ray.oct_inv4),
            prim => self.casters[prim].blocks(&ray.s)
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn first_blocker_avx2(&self, ray: &ShadowRay) -> Option<u32> {
        traverse_until!(
            &self.bvh,
            ray.ray.direction,
            node => hit_mask(node, children_avx2(node, ray), ray.oct_inv4),
            prim => self.casters[prim].blocks(&ray.s)
        )
    }
}

/// obvhs's octant code of a direction (`oct_inv4`).
#[inline(always)]
fn octant(d: Vec3) -> u32 {
    (if d.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if d.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if d.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// Pushes `prim` unless `out` already holds `cap`; true when it was full (stop).
#[inline(always)]
fn push_capped(out: &mut Vec<u32>, prim: usize, cap: usize) -> bool {
    if out.len() >= cap {
        return true;
    }
    out.push(prim as u32);
    false
}

/// The node's hit mask in obvhs's layout (internal children in the high byte by traversal
/// priority, leaf primitives in the low 24 bits) from the children whose boxes the ray meets
/// (bit `j` of `children`: child slot `j`).
#[inline(always)]
fn hit_mask(node: &CwBvhNode, mut children: u32, oct_inv4: u32) -> u32 {
    let (bits, index) = node.get_child_and_index_bits(oct_inv4);
    let mut mask = 0;
    while children != 0 {
        let j = children.trailing_zeros() as usize;
        children &= children - 1;
        mask |= extract_byte64(bits, j) << extract_byte64(index, j);
    }
    mask
}

/// The ray in the node's quantized frame: per axis the scale and offset that turn a child
/// plane's byte `q` into the ray's distance `q · scale + offset` to it.
#[inline(always)]
fn node_frame(node: &CwBvhNode, ray: &ShadowRay) -> (Vec3A, Vec3A) {
    let inv = ray.ray.inv_direction;
    (
        node.compute_extent() * inv,
        (Vec3A::from(node.p) - ray.ray.origin) * inv,
    )
}

/// The child planes' bytes of each axis, (entered, left) for the ray's direction.
#[inline(always)]
fn slabs<'a>(node: &'a CwBvhNode, ray: &ShadowRay) -> [(&'a [u8; 8], &'a [u8; 8]); 3] {
    let pick = |neg: bool, lo: &'a [u8; 8], hi: &'a [u8; 8]| if neg { (hi, lo) } else { (lo, hi) };
    [
        pick(ray.neg[0], &node.child_min_x, &node.child_max_x),
        pick(ray.neg[1], &node.child_min_y, &node.child_max_y),
        pick(ray.neg[2], &node.child_min_z, &node.child_max_z),
    ]
}

/// The child-box test one child at a time: bit `j` set where the ray meets child slot `j`'s box.
#[inline(always)]
fn children_scalar(node: &CwBvhNode, ray: &ShadowRay) -> u32 {
    let (scale, offset) = node_frame(node, ray);
    let [x, y, z] = slabs(node, ray);
    let mut children = 0;
    for j in 0..8 {
        let t = |q: u8, k: usize| f32::from(q) * scale[k] + offset[k];
        let near = t(x.0[j], 0).max(t(y.0[j], 1)).max(t(z.0[j], 2)).max(0.0);
        let far = t(x.1[j], 0)
            .min(t(y.1[j], 1))
            .min(t(z.1[j], 2))
            .min(ray.s.len);
        if near <= far {
            children |= 1 << j;
        }
    }
    children
}

/// The child-box test four children at a time (SSE2): the bits of [`children_scalar`].
#[inline]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn children_sse2(node: &CwBvhNode, ray: &ShadowRay) -> u32 {
    use std::arch::x86_64::*;
    let (scale, offset) = node_frame(node, ray);
    let [x, y, z] = slabs(node, ray);
    let zero = _mm_setzero_si128();
    // Eight bytes as two vectors of four floats.
    let bytes = |q: &[u8; 8]| {
        let w = _mm_unpacklo_epi8(_mm_cvtsi64_si128(i64::from_le_bytes(*q)), zero);
        (
            _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, zero)),
            _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, zero)),
        )
    };
    let axis = |q: &[u8; 8], k: usize| {
        let (s, o) = (_mm_set1_ps(scale[k]), _mm_set1_ps(offset[k]));
        let (lo, hi) = bytes(q);
        (
            _mm_add_ps(_mm_mul_ps(lo, s), o),
            _mm_add_ps(_mm_mul_ps(hi, s), o),
        )
    };
    let (xn, yn, zn) = (axis(x.0, 0), axis(y.0, 1), axis(z.0, 2));
    let (xf, yf, zf) = (axis(x.1, 0), axis(y.1, 1), axis(z.1, 2));
    let (tmin, tmax) = (_mm_setzero_ps(), _mm_set1_ps(ray.s.len));
    let half = |xn: __m128, yn: __m128, zn: __m128, xf: __m128, yf: __m128, zf: __m128| {
        let near = _mm_max_ps(_mm_max_ps(xn, yn), _mm_max_ps(zn, tmin));
        let far = _mm_min_ps(_mm_min_ps(xf, yf), _mm_min_ps(zf, tmax));
        _mm_movemask_ps(_mm_cmple_ps(near, far)) as u32
    };
    half(xn.0, yn.0, zn.0, xf.0, yf.0, zf.0) | half(xn.1, yn.1, zn.1, xf.1, yf.1, zf.1) << 4
}

/// The child-box test of all eight children in one vector (AVX2, FMA): the bits of
/// [`children_scalar`].
#[inline]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn children_avx2(node: &CwBvhNode, ray: &ShadowRay) -> u32 {
    use std::arch::x86_64::*;
    let (scale, offset) = node_frame(node, ray);
    let [x, y, z] = slabs(node, ray);
    let plane = |q: &[u8; 8], k: usize| {
        let f = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(i64::from_le_bytes(
            *q,
        ))));
        _mm256_fmadd_ps(f, _mm256_set1_ps(scale[k]), _mm256_set1_ps(offset[k]))
    };
    let near = _mm256_max_ps(
        _mm256_max_ps(plane(x.0, 0), plane(y.0, 1)),
        _mm256_max_ps(plane(z.0, 2), _mm256_setzero_ps()),
    );
    let far = _mm256_min_ps(
        _mm256_min_ps(plane(x.1, 0), plane(y.1, 1)),
        _mm256_min_ps(plane(z.1, 2), _mm256_set1_ps(ray.s.len)),
    );
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
}

/// The cone's child-box test, one child at a time (the boxes decoded to local coordinates).
#[inline(always)]
fn cone_hits(node: &CwBvhNode, cone: &Cone, oct_inv4: u32) -> u32 {
    let e = node.compute_extent();
    let p = Vec3A::from(node.p);
    let mut children = 0;
    for j in 0..8 {
        if node.child_meta[j] == 0 {
            continue;
        }
        let lo = Vec3A::new(
            f32::from(node.child_min_x[j]),
            f32::from(node.child_min_y[j]),
            f32::from(node.child_min_z[j]),
        ) * e
            + p;
        let hi = Vec3A::new(
            f32::from(node.child_max_x[j]),
            f32::from(node.child_max_y[j]),
            f32::from(node.child_max_z[j]),
        ) * e
            + p;
        if cone.may_meet(lo.into(), hi.into()) {
            children |= 1 << j;
        }
    }
    hit_mask(node, children, oct_inv4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generators::{self, GeneratorParams};
    use crate::util::hash::{mix64, unit_f32};

    fn flat(name: &str) -> FlatMesh {
        generators::find(name)
            .unwrap()
            .build(&GeneratorParams::default())
            .flatten()
    }

    /// A point in the box `[lo, hi]` from the stream `s`.
    fn point(s: u64, lo: Vec3, hi: Vec3) -> Vec3 {
        let u = Vec3::new(
            unit_f32(mix64(s)),
            unit_f32(mix64(s ^ 1)),
            unit_f32(mix64(s ^ 2)),
        );
        lo + (hi - lo) * u
    }

    /// Whether any casting triangle blocks `ray`: every caster tested, no tree.
    fn brute_force(bvh: &ShadowBvh, ray: &ShadowRay) -> bool {
        bvh.casters.iter().any(|c| {
            let (a, b, cc) = (c.v[0], c.v[1], c.v[2]);
            let n = (b - a).cross(cc - a);
            let (o, d, len) = ray.s.parts();
            let t = n.dot(a - o) / n.dot(d);
            t >= 0.0 && t < len && coverage::line_crosses(o, d, n, &[(a, b), (b, cc), (cc, a)])
        })
    }

    /// On every instruction set, the traversal answers as the test of every caster does, for
    /// random segments through a scene's casters.
    #[test]
    fn every_instruction_set_answers_as_testing_every_caster() {
        let flat = flat("sphere-grid");
        let bvh = ShadowBvh::of_scene(&flat);
        assert!(
            bvh.len() < flat.mesh.triangles.len(),
            "the ground casts nothing"
        );
        let b = flat.mesh.bounds();
        let (lo, hi) = (b.min - Vec3::ONE, b.max + Vec3::ONE);
        for isa in Isa::available() {
            let mut blocked = 0;
            for i in 0..4000u64 {
                let (from, to) = (point(2 * i, lo, hi), point(2 * i + 1, lo, hi));
                let ray = bvh.ray(from, to).unwrap();
                let want = brute_force(&bvh, &ray);
                assert_eq!(
                    bvh.occluded_ray(isa, &ray, &mut None),
                    want,
                    "{}: segment {i} {from} → {to}",
                    isa.name()
                );
                blocked += usize::from(want);
            }
            assert!(blocked > 100 && blocked < 3900, "{blocked} of 4000 blocked");
        }
    }

    /// A closed octahedron blocks every segment from outside to its centre, also those through
    /// its vertices and the midpoints of its edges exactly (ties of the coverage rule on shared
    /// edges and vertices), on every instruction set, one ray at a time and as a group.
    #[test]
    fn a_closed_mesh_blocks_rays_through_its_shared_edges_and_vertices() {
        let positions = vec![
            Vec3::X,
            Vec3::NEG_X,
            Vec3::Y,
            Vec3::NEG_Y,
            Vec3::Z,
            Vec3::NEG_Z,
        ];
        let mut triangles = Vec::new();
        for (x, y, z) in [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4)] {
            triangles.push([x, y, z]);
            triangles.push([y, x, 5]);
        }
        let flat = FlatMesh {
            mesh: crate::scene::Mesh {
                positions: positions.clone(),
                triangles: triangles.clone(),
            },
            object_of_triangle: vec![0; triangles.len()],
            roles: vec![crate::scene::Role::BOTH],
        };
        let bvh = ShadowBvh::of_scene(&flat);
        let mut through: Vec<Vec3> = positions.clone();
        for t in &triangles {
            for k in 0..3 {
                let (p, q) = (positions[t[k] as usize], positions[t[(k + 1) % 3] as usize]);
                through.push((p + q) * 0.5);
            }
            through.push(t.iter().map(|&v| positions[v as usize]).sum::<Vec3>() / 3.0);
        }
        let (mut candidates, mut facing) = (Vec::new(), Vec::new());
        for isa in Isa::available() {
            for &p in &through {
                let from = p * 3.0;
                let ray = bvh.ray(from, Vec3::ZERO).unwrap();
                assert!(brute_force(&bvh, &ray), "{p}: the coverage rule leaks");
                assert!(
                    bvh.occluded_ray(isa, &ray, &mut None),
                    "{}: {p} leaks",
                    isa.name()
                );
                let group = bvh.gather(isa, from, Vec3::ZERO, 0.1, 16, &mut candidates);
                assert_eq!(group, Gathered::Few, "{p}");
                bvh.facing_among(&candidates, from, &mut facing);
                assert!(
                    ShadowBvh::occluded_among(&mut facing, &ray.s),
                    "{p}: group leaks"
                );
                assert_eq!(
                    bvh.occluded_packet(isa, &[ray, ray], &mut PacketStack::default()),
                    0b11,
                    "{p}: packet leaks"
                );
            }
        }
    }

    /// A packet of rays from one point answers ray by ray as testing every caster does, on
    /// every instruction set, for full and partial packets, with and without the previous
    /// packet's blocker as a hint.
    #[test]
    fn a_packet_answers_as_testing_every_caster() {
        let flat = flat("sphere-grid");
        let bvh = ShadowBvh::of_scene(&flat);
        let b = flat.mesh.bounds();
        let (lo, hi) = (b.min - Vec3::ONE, b.max + Vec3::ONE);
        let mut stack = PacketStack::default();
        let (mut blocked, mut rays) = (0, 0);
        for isa in Isa::available() {
            for i in 0..150u64 {
                let from = point(mix64(i), lo, hi);
                // A narrow bundle towards one point (as from a shading point to a light) or
                // rays spread everywhere.
                let towards = point(mix64(i ^ 0xabc), lo, hi);
                let n = [PACKET, 37, 1][i as usize % 3];
                let packet: Vec<ShadowRay> = (0..n as u64)
                    .map(|j| {
                        let to = if i % 2 == 0 {
                            towards + (point(mix64(i * 97 + j), lo, hi) - towards) * 0.05
                        } else {
                            point(mix64(i * 97 + j), lo, hi)
                        };
                        bvh.ray(from, to).unwrap()
                    })
                    .collect();
                let got = bvh.occluded_packet(isa, &packet, &mut stack);
                if n < PACKET {
                    assert_eq!(got >> n, 0, "bits beyond the packet");
                }
                for (r, ray) in packet.iter().enumerate() {
                    let want = brute_force(&bvh, ray);
                    assert_eq!(
                        got >> r & 1 == 1,
                        want,
                        "{}: packet {i} ray {r}",
                        isa.name()
                    );
                    blocked += usize::from(want);
                    rays += 1;
                }
            }
        }
        assert!(
            blocked > rays / 10 && blocked < rays * 9 / 10,
            "{blocked} of {rays} blocked"
        );
    }

    /// The packet traversal refuses rays from different points (its shared-origin triangle
    /// test would answer wrongly).
    #[test]
    #[should_panic(expected = "start at one point")]
    fn a_packet_from_two_points_is_refused() {
        let bvh = ShadowBvh::of_scene(&flat("sphere-grid"));
        let rays = [
            bvh.ray(Vec3::ZERO, Vec3::ONE).unwrap(),
            bvh.ray(Vec3::X, Vec3::ONE).unwrap(),
        ];
        bvh.occluded_packet(Isa::host(), &rays, &mut PacketStack::default());
    }

    /// What a group gathers holds every caster that blocks a ray from its point to a point of
    /// the light's sphere: the rays answer the same among the candidates as through the tree.
    #[test]
    fn a_gathered_group_holds_every_blocker_of_its_rays() {
        let flat = flat("blob-on-plane");
        let bvh = ShadowBvh::of_scene(&flat);
        let b = flat.mesh.bounds();
        let (centre, radius) = (Vec3::new(0.5, 4.0, -0.3), 0.6);
        let mut seen = [0usize; 3];
        let (mut candidates, mut facing) = (Vec::new(), Vec::new());
        for i in 0..400u64 {
            let from = point(7 * i, b.min, Vec3::new(b.max.x, b.min.y + 0.5, b.max.z));
            for isa in Isa::available() {
                let got = bvh.gather(isa, from, centre, radius, 64, &mut candidates);
                bvh.facing_among(&candidates, from, &mut facing);
                seen[got as usize] += 1;
                for j in 0..32u64 {
                    let dir = point(mix64(i * 64 + j), -Vec3::ONE, Vec3::ONE);
                    let to = centre + dir.normalize_or_zero() * radius * unit_f32(mix64(j));
                    let ray = bvh.ray(from, to).unwrap();
                    let want = bvh.occluded_ray(isa, &ray, &mut None);
                    match got {
                        Gathered::Empty => assert!(!want, "point {i}, ray {j}: blocked"),
                        Gathered::Few => assert_eq!(
                            ShadowBvh::occluded_among(&mut facing, &ray.s),
                            want,
                            "point {i}, ray {j}"
                        ),
                        Gathered::Many => {}
                    }
                }
            }
        }
        assert!(
            seen.iter().all(|&n| n > 0),
            "empty, few and many groups: {seen:?}"
        );
    }
}

/// [`cone_hits`] with the eight children in one vector (AVX2, FMA): the same test, its
/// rounding within the cone's margins.
#[inline]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn cone_hits_avx2(node: &CwBvhNode, cone: &Cone, oct_inv4: u32) -> u32 {
    use std::arch::x86_64::*;
    let e = node.compute_extent();
    let bytes = |q: &[u8; 8]| {
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(i64::from_le_bytes(
            *q,
        ))))
    };
    // Per axis the children's box centres and extents.
    let axis = |lo: &[u8; 8], hi: &[u8; 8], e: f32, p: f32| {
        let (e, p) = (_mm256_set1_ps(e), _mm256_set1_ps(p));
        let (lo, hi) = (
            _mm256_fmadd_ps(bytes(lo), e, p),
            _mm256_fmadd_ps(bytes(hi), e, p),
        );
        (
            _mm256_mul_ps(_mm256_add_ps(lo, hi), _mm256_set1_ps(0.5)),
            _mm256_sub_ps(hi, lo),
        )
    };
    let (cx, ex) = axis(&node.child_min_x, &node.child_max_x, e.x, node.p.x);
    let (cy, ey) = axis(&node.child_min_y, &node.child_max_y, e.y, node.p.y);
    let (cz, ez) = axis(&node.child_min_z, &node.child_max_z, e.z, node.p.z);
    let length = |x: __m256, y: __m256, z: __m256| {
        _mm256_sqrt_ps(_mm256_fmadd_ps(
            x,
            x,
            _mm256_fmadd_ps(y, y, _mm256_mul_ps(z, z)),
        ))
    };
    let rho = _mm256_fmadd_ps(
        length(ex, ey, ez),
        _mm256_set1_ps(0.5),
        _mm256_set1_ps(cone.slack),
    );
    let vx = _mm256_sub_ps(cx, _mm256_set1_ps(cone.apex.x));
    let vy = _mm256_sub_ps(cy, _mm256_set1_ps(cone.apex.y));
    let vz = _mm256_sub_ps(cz, _mm256_set1_ps(cone.apex.z));
    let dist = length(vx, vy, vz);
    let (ax, ay, az) = (
        _mm256_set1_ps(cone.axis.x),
        _mm256_set1_ps(cone.axis.y),
        _mm256_set1_ps(cone.axis.z),
    );
    let along = _mm256_fmadd_ps(vx, ax, _mm256_fmadd_ps(vy, ay, _mm256_mul_ps(vz, az)));
    let across = length(
        _mm256_fmsub_ps(vy, az, _mm256_mul_ps(vz, ay)),
        _mm256_fmsub_ps(vz, ax, _mm256_mul_ps(vx, az)),
        _mm256_fmsub_ps(vx, ay, _mm256_mul_ps(vy, ax)),
    );
    let within_reach =
        _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_sub_ps(dist, rho), _mm256_set1_ps(cone.reach));
    let apex_inside = _mm256_cmp_ps::<_CMP_LE_OQ>(dist, rho);
    let surface = _mm256_fmsub_ps(
        across,
        _mm256_set1_ps(cone.cos),
        _mm256_mul_ps(along, _mm256_set1_ps(cone.sin)),
    );
    let meets = _mm256_or_ps(apex_inside, _mm256_cmp_ps::<_CMP_LE_OQ>(surface, rho));
    let children = _mm256_movemask_ps(_mm256_and_ps(within_reach, meets)) as u32;
    hit_mask(node, children, oct_inv4)
}
