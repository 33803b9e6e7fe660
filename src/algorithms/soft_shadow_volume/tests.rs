use glam::{Vec2, Vec3};

use super::*;
use crate::util::hash::unit_pair;

fn rng(seed: u64, i: u64) -> Vec2 {
    unit_pair(seed, i) * 2.0 - Vec2::ONE
}

#[test]
fn chord_across_the_square_covers_the_strip_beyond_it() {
    // A horizontal edge at v = 0.5 across the whole light: the strip 0.5 ≤ v ≤ 1 is covered.
    let (c0, c1) = EmitterShape::Square
        .clip(Vec2::new(-3.0, 0.5), Vec2::new(3.0, 0.5))
        .unwrap();
    assert!((c0 - Vec2::new(-1.0, 0.5)).length() < 1e-6);
    assert!((exact_coverage(EmitterShape::Square, c0, c1) - 0.25).abs() < 1e-6);
    assert!((exact_coverage(EmitterShape::Square, c1, c0) - 0.25).abs() < 1e-6);
}

#[test]
fn chord_across_the_disc_covers_the_circular_segment() {
    // (A chord through the centre is the measure-zero case where the pass-1 quad's plane
    // passes through the point; its coverage is defined as 0.)
    for d in [0.05f32, 0.3, 0.8] {
        let (c0, c1) = EmitterShape::Disc
            .clip(Vec2::new(-2.0, d), Vec2::new(2.0, d))
            .unwrap();
        let expected = (d.acos() - d * (1.0 - d * d).sqrt()) / std::f32::consts::PI;
        let got = exact_coverage(EmitterShape::Disc, c0, c1);
        assert!(
            (got - expected).abs() < 1e-5,
            "d = {d}: {got} vs {expected}"
        );
    }
}

/// Area fraction of the square covered by a convex polygon, by clipping the square with the
/// polygon's edges: independent of the per-edge coverage sum.
fn covered_fraction_by_clipping(poly: &[Vec2]) -> f32 {
    let mut sq = vec![
        Vec2::new(-1.0, -1.0),
        Vec2::new(1.0, -1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(-1.0, 1.0),
    ];
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        sq = clip_half_plane(&sq, |x| (b - a).perp_dot(x - a));
    }
    polygon_area(&sq) / 4.0
}

#[test]
fn greens_theorem_sum_over_a_loop_is_the_covered_area() {
    // III §3.2.2: per-edge signed coverage plus the hard-shadow term (is the light centre behind
    // the occluder?) is the covered fraction of the light, for any convex occluder outline.
    for seed in 0..200u64 {
        let mut tri = [rng(seed, 0) * 1.6, rng(seed, 1) * 1.6, rng(seed, 2) * 1.6];
        if (tri[1] - tri[0]).perp_dot(tri[2] - tri[0]) < 0.0 {
            tri.swap(1, 2);
        }
        let centre_inside = (0..3).all(|i| (tri[(i + 1) % 3] - tri[i]).perp_dot(-tri[i]) >= 0.0);
        let mut sum = if centre_inside { 1.0 } else { 0.0 };
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            if let Some((c0, c1)) = EmitterShape::Square.clip(a, b) {
                let side = a.perp_dot(b).signum();
                sum -= side * exact_coverage(EmitterShape::Square, c0, c1);
            }
        }
        let expected = covered_fraction_by_clipping(&tri);
        assert!(
            (sum - expected).abs() < 1e-4,
            "seed {seed}: {sum} vs {expected}"
        );
    }
}

#[test]
fn projection_onto_the_light_follows_similar_triangles() {
    let light = Light::Rect {
        center: Vec3::new(0.0, 10.0, 0.0),
        half_u: Vec3::new(1.0, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 1.0),
    };
    let e = Emitter::seen_from(&light, Vec3::ZERO);
    // Halfway to the light the projection doubles distances from the axis.
    let (q0, q1) = e
        .project_edge(
            Vec3::ZERO,
            Vec3::new(-1.0, 5.0, 0.25),
            Vec3::new(1.0, 5.0, 0.25),
        )
        .unwrap();
    assert!((q0 - Vec2::new(-2.0, 0.5)).length() < 1e-5, "{q0}");
    assert!((q1 - Vec2::new(2.0, 0.5)).length() < 1e-5, "{q1}");
    // An edge entirely below the point projects nowhere; one crossing its plane is clipped and
    // its far end runs off the light.
    assert!(e
        .project_edge(
            Vec3::ZERO,
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(1.0, -2.0, 0.0)
        )
        .is_none());
    let (q0, q1) = e
        .project_edge(
            Vec3::ZERO,
            Vec3::new(0.1, 5.0, 0.0),
            Vec3::new(0.1, -5.0, 3.0),
        )
        .unwrap();
    assert!((q0 - Vec2::new(0.2, 0.0)).length() < 1e-5);
    assert!(q1.length() > 100.0);
}

/// Points around an edge whose projected edge meets the light: the edge's penumbra volume.
fn penumbra_points(light: &Light, a: Vec3, b: Vec3, seed: u64) -> Vec<Vec3> {
    (0..4000u64)
        .filter_map(|i| {
            let r = rng(seed, 3 * i);
            let s = rng(seed, 3 * i + 1);
            let p =
                a.lerp(b, (s.y + 1.0) * 0.5) + Vec3::new(r.x * 1.5, (s.x - 1.0) * 1.5, r.y * 1.5);
            let e = Emitter::seen_from(light, p);
            let (q0, q1) = e.project_edge(p, a, b)?;
            e.shape.clip(q0, q1).map(|_| p)
        })
        .collect()
}

#[test]
fn wedges_enclose_the_penumbra_volume_and_tighter_wedges_are_smaller() {
    let rect = Light::Rect {
        center: Vec3::new(0.3, 6.0, -0.2),
        half_u: Vec3::new(1.0, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 0.6),
    };
    let Light::Rect {
        center,
        half_u,
        half_v,
    } = rect
    else {
        unreachable!()
    };
    let corners = [
        center - half_u - half_v,
        center + half_u - half_v,
        center + half_u + half_v,
        center - half_u + half_v,
    ];
    let sphere = Light::Sphere {
        center,
        radius: 0.8,
    };
    let reach = 100.0;
    for seed in 0..6u64 {
        // Edges at different distances from the light exercise the moved vertex.
        let a = Vec3::new(rng(seed, 90).x, 2.0 + rng(seed, 91).x, rng(seed, 92).x);
        let b = a + Vec3::new(1.2, rng(seed, 93).x * 0.8, rng(seed, 94).x);
        let tight = Wedge::tight_rect(a, b, corners, reach).unwrap();
        let robust = Wedge::robust(a, b, center, (half_u + half_v).length(), reach).unwrap();
        let penumbra = penumbra_points(&rect, a, b, seed);
        assert!(penumbra.len() > 50);
        for p in &penumbra {
            assert!(
                tight.volume.contains(*p),
                "seed {seed}: {p} outside tight wedge"
            );
            assert!(
                robust.volume.contains(*p),
                "seed {seed}: {p} outside robust wedge"
            );
        }
        let sphere_wedge = Wedge::robust(a, b, center, 0.8, reach).unwrap();
        for p in penumbra_points(&sphere, a, b, seed) {
            assert!(sphere_wedge.volume.contains(p), "seed {seed}: {p} outside");
        }
        // IV §4.1: the wedge from the rectangle is tighter than the one from its bounding sphere.
        let count = |w: &Wedge| {
            (0..4000u64)
                .filter(|&i| {
                    let (r, s) = (rng(seed + 7, 2 * i), rng(seed + 7, 2 * i + 1));
                    w.volume.contains(
                        a.lerp(b, (s.y + 1.0) * 0.5)
                            + Vec3::new(r.x * 1.5, (s.x - 1.0) * 1.5, r.y * 1.5),
                    )
                })
                .count()
        };
        assert!(count(&tight) < count(&robust));
    }
}

#[test]
fn split_12_bit_buffer_adds_with_carries_until_32_full_contributions() {
    let mut rgba = [0u8; 4];
    let mut sum = 0.0f32;
    for i in 0..30u64 {
        let c = unit_pair(5, i).x;
        sum += c;
        rgba = split12::blend(rgba, split12::split(c));
    }
    // Each contribution is rounded to 12 bits: at most half a step each.
    let step = 1.0 / split12::MAX as f32;
    assert!((split12::value(rgba) - sum).abs() <= 30.0 * 0.5 * step + 1e-4);
    // Beyond the carry range the channels saturate and the sum is lost.
    let mut full = [0u8; 4];
    for _ in 0..40 {
        full = split12::blend(full, split12::split(1.0));
    }
    assert!(split12::value(full) < 40.0 - 1.0);
}

#[test]
fn overlap_approximation_lies_between_disjoint_and_nested_occluders() {
    // IV §5.1, Figure 7: 16 % and 4 % cover 20 % when disjoint and 16 % when nested.
    let c = overlap_coverage(0.16, 0.04);
    assert!(c > 0.16 && c < 0.20);
    for i in 0..100u64 {
        let r = unit_pair(9, i);
        let c = overlap_coverage(r.x, r.y);
        assert!(c >= r.x.max(r.y) && c <= (r.x + r.y).min(1.0) + 1e-6);
    }
}

#[test]
fn silhouettes_of_separate_objects_form_separate_loops() {
    use crate::scene::adjacency::EdgeAdjacency;
    use crate::scene::generators::primitives;
    let mut m = primitives::cuboid(Vec3::ZERO, Vec3::ONE);
    m.append(&primitives::cuboid(
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::new(4.0, 1.0, 1.0),
    ));
    let s = EdgeAdjacency::build(&m).silhouette_from(Vec3::new(2.0, 10.0, 0.5));
    let loops = silhouette_loops(&s.edges);
    assert_eq!(loops.len(), 2);
    assert_eq!(loops.iter().map(|l| l.len()).sum::<usize>(), s.edges.len());
}

#[test]
fn light_splitting_tiles_the_rectangle() {
    let light = Light::Rect {
        center: Vec3::new(1.0, 5.0, 0.0),
        half_u: Vec3::new(0.9, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 0.6),
    };
    for k in 1..=3 {
        let subs = split_light(&light, k).unwrap();
        assert_eq!(subs.len() as u32, k * k);
        let area: f32 = subs.iter().map(|l| l.area()).sum();
        assert!((area - light.area()).abs() < 1e-4);
        let mean = subs.iter().map(|l| l.center()).sum::<Vec3>() / subs.len() as f32;
        assert!((mean - light.center()).length() < 1e-5);
    }
    let sphere = Light::Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
    };
    assert!(split_light(&sphere, 2).is_err());
}

#[test]
fn coverage_texture_agrees_with_exact_clipping() {
    for shape in [EmitterShape::Square, EmitterShape::Disc] {
        let t = CoverageTexture::build(shape, 32);
        let (mut sum, mut count) = (0.0f32, 0);
        for i in 0..2000u64 {
            let Some((c0, c1)) = shape.clip(rng(11, 2 * i) * 2.0, rng(11, 2 * i + 1) * 2.0) else {
                continue;
            };
            sum += (t.lookup(c0, c1) - exact_coverage(shape, c0, c1)).abs();
            count += 1;
        }
        assert!(count > 500);
        assert!(
            sum / (count as f32) < 0.01,
            "{shape:?}: {}",
            sum / count as f32
        );
    }
}

#[test]
fn options_name_the_bad_field_and_value() {
    let mut o = std::collections::BTreeMap::new();
    o.insert(ID.to_string(), serde_json::json!({ "light_split": 5 }));
    let e = crate::algorithms::find(ID)
        .unwrap()
        .check_options(&o)
        .unwrap_err();
    assert_eq!(
        e.field.as_deref(),
        Some("$.options.soft_shadow_volume.light_split")
    );
    assert!(e.message.contains('5'));
    o.insert(ID.to_string(), serde_json::json!({ "coverage": "magic" }));
    let e = crate::algorithms::find(ID)
        .unwrap()
        .check_options(&o)
        .unwrap_err();
    assert_eq!(
        e.field.as_deref(),
        Some("$.options.soft_shadow_volume.coverage")
    );
    o.insert(ID.to_string(), serde_json::json!({ "culling": true }));
    assert!(crate::algorithms::find(ID)
        .unwrap()
        .check_options(&o)
        .is_err());
}

/// The raster pipeline's front faces of a convex volume against the cube's analytic answer:
/// the cube [-1, 1]³ seen from (5, 5, 5) shows three faces of area 4 (triangles summing to
/// 12, each on its face's plane), seen from (0, 0, 5) one; bounds smaller than the cube cut
/// the faces to the bounds (the +z face of bounds [-0.5, 0.5]³: area 1), and a near plane
/// in front of an eye inside the cube is the one face drawn (area 4 on z = 0.5). The back
/// faces (IV §4.4's second culling pass), those whose plane has the eye on its inner side, are
/// the other three (area 12, each on a face at −1) from (5, 5, 5), the four sides and the
/// bottom from (0, 0, 5) (4 × 4 + 4 = 20; the bottom 4), and from inside the cube with the near
/// plane cutting it at z = 0.5 the five faces below it (4 + 4 × 3 = 16).
#[test]
fn front_and_back_faces_are_the_faces_the_eye_sees_and_the_far_ones() {
    use crate::algorithms::eye_raster::ConvexVolume;
    use crate::scene::Bounds;
    let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
    let cube = ConvexVolume {
        planes: axes.iter().map(|&n| (n, 1.0)).collect(),
    };
    let bounds = |h: f32| Bounds {
        min: Vec3::splat(-h),
        max: Vec3::splat(h),
    };
    // A near plane far behind every eye: it cuts nothing.
    let no_near = (Vec3::Z, 100.0);
    let area = |tris: &[Vec3]| -> f32 {
        tris.chunks(3)
            .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
            .sum()
    };
    // The faces are drawn with the planes pushed out by the margin: the cube's half-side g.
    let g = 1.0 + raster::WEDGE_MARGIN * bounds(3.0).diagonal();
    let close = |a: f32, b: f32| (a - b).abs() < 1e-3;
    let corner = raster::faces(&cube, &bounds(3.0), no_near, Vec3::splat(5.0), true);
    assert!(close(area(&corner), 12.0 * g * g), "{}", area(&corner));
    assert!(corner.iter().all(|p| p.max_element() > g - 1e-4));
    let above = raster::faces(&cube, &bounds(3.0), no_near, Vec3::new(0.0, 0.0, 5.0), true);
    assert!(close(area(&above), 4.0 * g * g), "{}", area(&above));
    assert!(above.iter().all(|p| (p.z - g).abs() < 1e-4));
    let cut = raster::faces(&cube, &bounds(0.5), no_near, Vec3::new(0.0, 0.0, 5.0), true);
    assert!(close(area(&cut), 1.0), "{}", area(&cut));
    // The eye inside the cube looking down -z: the near plane z ≤ 0.5 is the only front face.
    let near = (Vec3::Z, 0.5);
    let inside = raster::faces(&cube, &bounds(3.0), near, Vec3::new(0.0, 0.0, 0.9), true);
    assert!(close(area(&inside), 4.0 * g * g), "{}", area(&inside));
    assert!(inside.iter().all(|p| (p.z - 0.5).abs() < 1e-4));
    let far = raster::faces(&cube, &bounds(3.0), no_near, Vec3::splat(5.0), false);
    assert!(close(area(&far), 12.0 * g * g), "{}", area(&far));
    assert!(far.iter().all(|p| p.min_element() < -g + 1e-4));
    let below = raster::faces(
        &cube,
        &bounds(3.0),
        no_near,
        Vec3::new(0.0, 0.0, 5.0),
        false,
    );
    assert!(close(area(&below), 20.0 * g * g), "{}", area(&below));
    let bottom: Vec<Vec3> = below
        .chunks(3)
        .filter(|t| t.iter().all(|p| (p.z + g).abs() < 1e-4))
        .flatten()
        .copied()
        .collect();
    assert!(close(area(&bottom), 4.0 * g * g), "{}", area(&bottom));
    let cut_far = raster::faces(&cube, &bounds(3.0), near, Vec3::new(0.0, 0.0, 0.9), false);
    // The bottom and four sides from z = −g up to the near plane.
    let expected = 4.0 * g * g + 4.0 * 2.0 * g * (0.5 + g);
    assert!(close(area(&cut_far), expected), "{}", area(&cut_far));
}

/// The faces of a volume turned off the axes (so that the clipping rounds) share their corners
/// to the bit, front and back alike: the corners of every face, front and back, are the eight
/// corners of the turned cube and no near-copies of them, so the rasterizer covers a pixel on
/// an edge between two faces once and the culling's front and back faces cover the same
/// pixels.
#[test]
fn front_and_back_faces_share_their_corners_to_the_bit() {
    use crate::algorithms::eye_raster::ConvexVolume;
    use crate::scene::Bounds;
    let turn = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.2);
    let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
    let cube = ConvexVolume {
        planes: axes.iter().map(|&n| (turn * n, 1.0)).collect(),
    };
    let bounds = Bounds {
        min: Vec3::splat(-3.0),
        max: Vec3::splat(3.0),
    };
    let no_near = (Vec3::Z, 100.0);
    let eye = Vec3::new(4.0, 3.0, 5.0);
    let mut corners: Vec<[u32; 3]> = [true, false]
        .iter()
        .flat_map(|&front| raster::faces(&cube, &bounds, no_near, eye, front))
        .map(|p| p.to_array().map(f32::to_bits))
        .collect();
    corners.sort_unstable();
    corners.dedup();
    assert_eq!(corners.len(), 8, "{corners:?}");
}
