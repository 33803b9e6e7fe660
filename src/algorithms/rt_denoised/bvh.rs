//! The BVH of the casters that `rt_denoised`'s shadow rays traverse, flattened into the two
//! arrays every execution reads (the wgpu execution uploads them as storage buffers):
//!
//! - node records ([`NodePair`], 64 bytes, one cache line): the boxes of both children of an
//!   interior node and a reference to each, so one fetch tests both children;
//! - triangles ([`Tri`], 48 bytes), each leaf's contiguous.
//!
//! A reference ([`leaf_ref`]) is a node record's index, or a leaf: bit 31 set, the triangle
//! count less one in bits 27–30 (at most [`MAX_LEAF`]) and the first triangle in bits 0–26. The
//! tree is a binary BVH built by PLOC (obvhs, Meister and Bittner 2018) over the occluders'
//! triangles only (a receiver-only object casts no shadow), leaves collapsed to at most
//! [`MAX_LEAF`] triangles by SAH cost; built on one host thread, so the tree, and the node
//! visits the model counts, are the same for any thread count. Boxes are recomputed from the
//! triangles in world coordinates and widened by [`pad`], so a ray that meets a triangle always
//! meets the boxes above it, however the slab test rounds.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};
use obvhs::triangle::Triangle;

use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::pass::gpu_struct;
use crate::scene::bvh::tie_breaking_box;

gpu_struct! {
    /// Both children of an interior node: each child's box and reference ([`leaf_ref`] or a
    /// node record's index).
    pub struct NodePair as "NodePair" {
        a_min: [f32; 3] => "vec3<f32>",
        a_ref: u32 => "u32",
        a_max: [f32; 3] => "vec3<f32>",
        a_pad: u32 => "u32",
        b_min: [f32; 3] => "vec3<f32>",
        b_ref: u32 => "u32",
        b_max: [f32; 3] => "vec3<f32>",
        b_pad: u32 => "u32",
    }
}

gpu_struct! {
    /// A caster triangle, world coordinates (each vertex padded to 16 bytes).
    pub struct Tri as "Tri" {
        v0: [f32; 3] => "vec3<f32>",
        p0: f32 => "f32",
        v1: [f32; 3] => "vec3<f32>",
        p1: f32 => "f32",
        v2: [f32; 3] => "vec3<f32>",
        p2: f32 => "f32",
    }
}

/// Bit 31 of a reference: a leaf.
pub const LEAF: u32 = 1 << 31;
/// Most triangles in a leaf.
pub const MAX_LEAF: u32 = 4;
/// The first triangle of a leaf must fit in 27 bits.
pub const MAX_TRIANGLES: usize = 1 << 27;
/// Depth of the traversal stack (entries per ray); a tree deeper than this is refused.
pub const STACK: usize = 64;

/// The reference of a leaf of `count` (1 to [`MAX_LEAF`]) triangles from `first`.
pub fn leaf_ref(first: u32, count: u32) -> u32 {
    LEAF | (count - 1) << 27 | first
}

/// A leaf reference's first triangle and triangle count.
pub fn leaf_range(r: u32) -> (u32, u32) {
    (r & ((1 << 27) - 1), ((r >> 27) & 0xf) + 1)
}

/// The flattened BVH of a frame's casters.
pub struct CasterBvh {
    pub nodes: Vec<NodePair>,
    pub triangles: Vec<Tri>,
    /// Where traversal starts: node record 0, a leaf (a tree of one leaf), or `None` without
    /// casters.
    pub root: Option<u32>,
    /// Levels of the tree (a root leaf is 1).
    pub depth: usize,
}

/// How much every box is widened on each side: 2⁻¹⁸ of the casters' diagonal plus their
/// largest coordinate magnitude, far above the slab test's rounding of `(b − o) / d` (a few
/// units in the last place of the larger of the two) and far below any feature a shadow shows.
pub fn pad(bounds: &Aabb) -> f32 {
    let span = bounds.diagonal().length() + bounds.min.abs().max(bounds.max.abs()).max_element();
    span * (1.0 / 262_144.0)
}

impl CasterBvh {
    /// The BVH of `frame`'s occluder triangles. Errors when there are more than
    /// [`MAX_TRIANGLES`] casters or the tree is deeper than [`STACK`].
    pub fn build(frame: &Frame) -> Result<CasterBvh> {
        let mesh = &frame.flat.mesh;
        let casters: Vec<[Vec3; 3]> = (0..mesh.triangles.len())
            .filter(|&t| frame.flat.role_of(t).occluder)
            .map(|t| mesh.triangle(t))
            .collect();
        if casters.len() > MAX_TRIANGLES {
            return Err(Error::Unsupported(format!(
                "rt_denoised: {} caster triangles, more than its BVH holds ({MAX_TRIANGLES})",
                casters.len()
            )));
        }
        if casters.is_empty() {
            return Ok(CasterBvh {
                nodes: vec![],
                triangles: vec![],
                root: None,
                depth: 0,
            });
        }
        let mut bounds = Aabb::empty();
        for t in &casters {
            for v in t {
                bounds.extend(Vec3A::from(*v));
            }
        }
        // The build sees the casters centred and scaled to a unit-sized scene, as the frame's
        // BVH does (`scene::bvh`), so the tie-breaking widening is relative to the scene.
        let diagonal = bounds.diagonal().length();
        let (origin, scale) = if diagonal.is_finite() && diagonal > 0.0 {
            (
                bounds.center(),
                2f32.powi(-(diagonal.log2().floor() as i32)),
            )
        } else {
            (Vec3A::ZERO, 1.0)
        };
        let local = |p: Vec3| (Vec3A::from(p) - origin) * scale;
        let boxes: Vec<Aabb> = casters
            .iter()
            .enumerate()
            .map(|(i, [a, b, c])| {
                let t = Triangle {
                    v0: local(*a),
                    v1: local(*b),
                    v2: local(*c),
                };
                tie_breaking_box(&t, i)
            })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .map_err(|e| Error::Unsupported(format!("rt_denoised: BVH build thread: {e}")))?;
        let bvh = pool.install(|| {
            let mut b = PlocBuilder::with_capacity(boxes.len()).build(
                PlocSearchDistance::Medium,
                &boxes,
                (0..boxes.len() as u32).collect(),
                SortPrecision::U64,
                3,
            );
            collapse(&mut b, MAX_LEAF, 3.0);
            b
        });
        let pad = pad(&bounds);
        let mut out = CasterBvh {
            nodes: Vec::new(),
            triangles: Vec::with_capacity(casters.len()),
            root: None,
            depth: 0,
        };
        // Depth-first, first child first: records in visit order, each leaf's triangles
        // appended as it is reached. `slot` is where the reference to the node goes: the root,
        // or side 0 / 1 of a record.
        enum Slot {
            Root,
            Side(usize, bool),
        }
        let mut todo = vec![(0usize, Slot::Root, 1usize)];
        while let Some((n, slot, level)) = todo.pop() {
            let node = &bvh.nodes[n];
            out.depth = out.depth.max(level);
            let reference = if node.is_leaf() {
                let first = out.triangles.len() as u32;
                let count = node.prim_count;
                if count > MAX_LEAF {
                    return Err(Error::Unsupported(format!(
                        "rt_denoised: a BVH leaf of {count} triangles (at most {MAX_LEAF})"
                    )));
                }
                for k in 0..count {
                    let i = bvh.primitive_indices[(node.first_index + k) as usize] as usize;
                    let [a, b, c] = casters[i];
                    out.triangles.push(Tri {
                        v0: a.to_array(),
                        v1: b.to_array(),
                        v2: c.to_array(),
                        ..Tri::default()
                    });
                }
                leaf_ref(first, count)
            } else {
                let record = out.nodes.len();
                out.nodes.push(NodePair::default());
                let first = node.first_index as usize;
                // The second child is pushed first, so the first is flattened next to its
                // parent.
                todo.push((first + 1, Slot::Side(record, true), level + 1));
                todo.push((first, Slot::Side(record, false), level + 1));
                record as u32
            };
            match slot {
                Slot::Root => out.root = Some(reference),
                Slot::Side(record, second) => {
                    let r = &mut out.nodes[record];
                    if second {
                        r.b_ref = reference;
                    } else {
                        r.a_ref = reference;
                    }
                }
            }
        }
        if out.depth > STACK {
            return Err(Error::Unsupported(format!(
                "rt_denoised: BVH of depth {} (its traversal stack holds {STACK})",
                out.depth
            )));
        }
        // Boxes bottom-up: records are in depth-first order, so a record's children come after
        // it; walking backwards, every child's box is known when its parent is set.
        let mut boxes_of: Vec<(Vec3, Vec3)> = vec![(Vec3::ZERO, Vec3::ZERO); out.nodes.len()];
        for record in (0..out.nodes.len()).rev() {
            let r = out.nodes[record];
            let a = out.box_of(r.a_ref, &boxes_of);
            let b = out.box_of(r.b_ref, &boxes_of);
            boxes_of[record] = (a.0.min(b.0), a.1.max(b.1));
            let widen = Vec3::splat(pad);
            let r = &mut out.nodes[record];
            r.a_min = (a.0 - widen).to_array();
            r.a_max = (a.1 + widen).to_array();
            r.b_min = (b.0 - widen).to_array();
            r.b_max = (b.1 + widen).to_array();
        }
        Ok(out)
    }

    /// The exact box (not widened) of the subtree `r` refers to: a leaf's from its triangles,
    /// a record's from `boxes_of`.
    fn box_of(&self, r: u32, boxes_of: &[(Vec3, Vec3)]) -> (Vec3, Vec3) {
        if r & LEAF == 0 {
            return boxes_of[r as usize];
        }
        let (first, count) = leaf_range(r);
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for t in &self.triangles[first as usize..(first + count) as usize] {
            for v in [t.v0, t.v1, t.v2] {
                lo = lo.min(Vec3::from(v));
                hi = hi.max(Vec3::from(v));
            }
        }
        (lo, hi)
    }

    /// Bytes of the node records and of the triangles.
    pub fn bytes(&self) -> (u64, u64) {
        (
            (self.nodes.len() * size_of::<NodePair>()) as u64,
            (self.triangles.len() * size_of::<Tri>()) as u64,
        )
    }
}
