//! Ray casting against the scene with a compressed wide BVH (obvhs).
//!
//! Used by the ground-truth reference (shadow rays) and by the eye pass (primary rays). Shadow
//! rays test the occluders only (objects whose role has `occluder`: a receiver-only object casts
//! no shadow, as in every algorithm that honours the role), through a BVH of the casting
//! triangles alone ([`ShadowBvh`], built beside this one); primary rays see every object. The
//! any-hit answer of a shadow ray depends only on the triangle tests, never on the tree's shape,
//! so results are identical whatever the build's thread count.
//!
//! The triangle test is the one coverage rule ([`coverage`]), not obvhs's Möller–Trumbore test,
//! which is not watertight (a ray through an edge shared by two triangles can miss both: the eye
//! pass then sees through a closed mesh and shadow rays leak light through it).

use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use super::coverage;
use super::mesh::FlatMesh;
use super::shadow_bvh::ShadowBvh;

/// The BVH holds the scene in local coordinates `(p − origin) · scale`: centred on its bounds
/// and scaled by a power of two to a diagonal in [1, 2), so that the tree's build and traversal
/// (quantized child boxes, fixed tolerances) see a well-conditioned scene whatever its offset
/// and scale. A vertex maps to one local point for every triangle using it (the mesh stays
/// watertight); the scaling is exact, the shift rounds within the coordinates' own precision.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Triangles in the BVH's leaf order, so traversal indexes them directly (local coordinates).
    triangles: Vec<Triangle>,
    /// Per triangle in leaf order: whether its object is an occluder (casts shadows).
    casts: Vec<bool>,
    origin: Vec3,
    scale: f32,
    /// The casting triangles' BVH, in the same local coordinates: what shadow rays traverse.
    shadow: ShadowBvh,
}

/// A primary-ray hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
}

impl SceneBvh {
    pub fn build(flat: &FlatMesh) -> SceneBvh {
        let (origin, scale) = local_frame(flat);
        let local = |p: Vec3| (p - origin) * scale;
        let triangles: Vec<Triangle> = (0..flat.mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = flat.mesh.triangle(t);
                Triangle {
                    v0: local(a).into(),
                    v1: local(b).into(),
                    v2: local(c).into(),
                }
            })
            .collect();
        let boxes: Vec<Aabb> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| tie_breaking_box(t, i))
            .collect();
        let bvh = if triangles.is_empty() {
            CwBvh::default()
        } else {
            obvhs::cwbvh::builder::build_cwbvh(
                &boxes,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        };
        let shadow = ShadowBvh::of_scene(flat);
        // Leaves refer to primitives through `primitive_indices`; store the triangles in that
        // order so the intersection callback indexes them directly.
        let order = &bvh.primitive_indices;
        let casts = order
            .iter()
            .map(|&i| flat.role_of(i as usize).occluder)
            .collect();
        let triangles = order.iter().map(|&i| triangles[i as usize]).collect();
        SceneBvh {
            bvh,
            triangles,
            casts,
            origin,
            scale,
            shadow,
        }
    }

    /// The casting triangles' BVH that shadow rays traverse.
    pub fn shadow(&self) -> &ShadowBvh {
        &self.shadow
    }

    /// `p` in the BVH's local coordinates.
    fn local(&self, p: Vec3) -> Vec3 {
        (p - self.origin) * self.scale
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether an occluder's triangle blocks the open segment from `from` to `to` (a shadow
    /// ray: receiver-only objects let it through), through the casters' BVH
    /// ([`ShadowBvh::occluded`]).
    pub fn occluded(&self, from: Vec3, to: Vec3) -> bool {
        self.shadow.occluded(from, to)
    }

    /// [`Self::occluded`] through this BVH of every triangle with obvhs's traversal, the
    /// receiver-only triangles rejected in the leaf test: the shadow-ray method before
    /// [`ShadowBvh`], kept as its check (the same answers) and as the baseline its speed is
    /// measured against (`examples/shadow_rays.rs`).
    pub fn occluded_in_scene_bvh(&self, from: Vec3, to: Vec3) -> bool {
        self.blocked(from, to, true)
    }

    /// Whether any triangle blocks the open segment from `from` to `to`, receiver-only objects'
    /// too (what a shadow map holding every surface sees).
    pub fn blocked_by_any(&self, from: Vec3, to: Vec3) -> bool {
        self.blocked(from, to, false)
    }

    /// Whether a triangle blocks the segment: an occluder's, or with `casters_only` false any.
    fn blocked(&self, from: Vec3, to: Vec3, casters_only: bool) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let (from, to) = (self.local(from), self.local(to));
        let d = to - from;
        let len = d.length();
        if len <= 0.0 {
            return false;
        }
        let ray = Ray::new(Vec3A::from(from), Vec3A::from(d / len), 0.0, len);
        !self
            .bvh
            .ray_traverse_miss(ray, |r, id| match casters_only && !self.casts[id] {
                true => f32::INFINITY,
                false => intersect(&self.triangles[id], r),
            })
    }

    /// The closest hit along a ray, if any.
    pub fn closest(&self, origin: Vec3, dir: Vec3) -> Option<Hit> {
        if self.triangles.is_empty() {
            return None;
        }
        let ray = Ray::new_inf(Vec3A::from(self.local(origin)), Vec3A::from(dir));
        let mut hit = RayHit::none();
        self.bvh
            .ray_traverse(ray, &mut hit, |r, id| intersect(&self.triangles[id], r))
            .then(|| Hit {
                t: hit.t / self.scale,
                triangle: self.bvh.primitive_indices[hit.primitive_id as usize],
            })
    }
}

/// The local coordinates of `flat`'s BVHs, `(p − origin) · scale` ([`SceneBvh`]): `(origin,
/// scale)`.
pub(crate) fn local_frame(flat: &FlatMesh) -> (Vec3, f32) {
    let bounds = flat.mesh.bounds();
    let diagonal = bounds.diagonal();
    if diagonal.is_finite() && diagonal > 0.0 {
        (
            bounds.center(),
            2f32.powi(-(diagonal.log2().floor() as i32)),
        )
    } else {
        (Vec3::ZERO, 1.0)
    }
}

/// Widening of a triangle's box in [`tie_breaking_box`], in local units (the scene's diagonal
/// is in [1, 2)): 2⁻¹⁸ ≈ 3.8·10⁻⁶, 32 `f32` steps at 1, far below any texel or sample spacing.
const TIE_BREAK: f32 = 1.0 / 262_144.0;

/// The box the BVH is built over for triangle `index`: its bounds widened on each of the six
/// sides by a different fraction of [`TIE_BREAK`] (a hash of the index and the side). The
/// PLOC builder merges only nodes that choose each other as the cheapest neighbour; among
/// neighbours of equal cost it always chooses the farthest one to the right, so a run of
/// nodes with identical boxes (N copies of one triangle, many zero-area triangles at one
/// place) merges one pair per pass and the build takes O(n²). Boxes that differ a little
/// break every tie, the passes merge a constant share of the nodes again and the build is
/// O(n log n) whatever the input. A wider box still holds its triangle, so traversal finds
/// the same hits; the boxes are deterministic, so the tree is the same on every run.
pub(crate) fn tie_breaking_box(tri: &Triangle, index: usize) -> Aabb {
    let mut h = (index as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut side = || {
        // splitmix64: six well-mixed fractions in [0.5, 1) from one index.
        h = h.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = h;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        TIE_BREAK * (0.5 + (z >> 40) as f32 / (1u64 << 25) as f32)
    };
    let b = tri.aabb();
    let low = Vec3A::new(side(), side(), side());
    let high = Vec3A::new(side(), side(), side());
    Aabb::new(b.min - low, b.max + high)
}

/// Distance along `ray` to `tri` within `[tmin, tmax]`, or infinity: whether the ray crosses
/// the triangle is decided by the one coverage rule ([`coverage::line_crosses`]), so a ray
/// through an edge or vertex shared by triangles of a closed mesh hits exactly one of them.
fn intersect(tri: &Triangle, ray: &Ray) -> f32 {
    let (a, b, c) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
    let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
    let n = (b - a).cross(c - a);
    let nd = n.dot(d);
    if nd == 0.0 {
        return f32::INFINITY;
    }
    // The plane's distance first: most candidates of a shadow ray are rejected by it, before
    // the three edge functions of the coverage rule.
    let t = n.dot(a - o) / nd;
    if t >= ray.tmin && t <= ray.tmax && coverage::line_crosses(o, d, n, &[(a, b), (b, c), (c, a)])
    {
        t
    } else {
        f32::INFINITY
    }
}
