//! Degenerate geometry never crashes the scene pipeline and never puts NaN or a value outside
//! [0, 1] into a visibility buffer. Property tests throw random triangle soups at it.

use super::common;

use common::{camera, degenerate_scenes, frame_of, object};
use glam::Vec3;
use proptest::prelude::*;
use shadowbench::algorithms::reference;
use shadowbench::scene::adjacency::EdgeAdjacency;
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Light, Mesh};

#[test]
fn reference_stays_in_range_on_degenerate_scenes() {
    for (name, frame) in degenerate_scenes() {
        let out = reference::render(&frame, 16, 3);
        out.visibility
            .check_range()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        // Silhouette extraction reports, never fails.
        let adj = EdgeAdjacency::build(&frame.scene.occluders());
        let _ = adj.silhouette_from(frame.scene.light.center());
    }
}

#[test]
fn light_inside_a_closed_mesh_sees_nothing() {
    let (_, frame) = degenerate_scenes()
        .into_iter()
        .find(|(n, _)| *n == "light inside a closed mesh")
        .unwrap();
    let out = reference::render(&frame, 16, 3);
    let mask = frame.gbuffer.mask();
    // Every ground pixel outside the cube's footprint is shadowed by the cube around the light.
    let lit = out
        .visibility
        .data
        .iter()
        .zip(&mask)
        .filter(|(v, m)| **m && **v > 0.0)
        .count();
    assert_eq!(lit, 0, "no light escapes a closed box around it");
}

fn vec3() -> impl Strategy<Value = Vec3> {
    (-3.0f32..3.0, -0.5f32..4.0, -3.0f32..3.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random triangle soups (with repeated indices, coincident points, light anywhere) give a
    /// visibility buffer in [0, 1] and silhouettes without panics.
    #[test]
    fn random_scenes_give_valid_visibility(
        points in prop::collection::vec(vec3(), 3..24),
        tris in prop::collection::vec((0usize..24, 0usize..24, 0usize..24), 1..32),
        light_at in vec3(),
        radius in 0.01f32..2.0,
        kind in 0u8..3,
    ) {
        let n = points.len();
        let mesh = Mesh {
            triangles: tris.iter().map(|&(a, b, c)| [(a % n) as u32, (b % n) as u32, (c % n) as u32]).collect(),
            positions: points,
        };
        let light = match kind {
            0 => Light::Sphere { center: light_at, radius },
            1 => Light::Disc { center: light_at, normal: Vec3::NEG_Y, radius },
            _ => Light::Rect { center: light_at, half_u: Vec3::X * radius, half_v: Vec3::Z * radius },
        };
        let frame = frame_of(vec![object(primitives::plane(4.0, 2)), object(mesh)], light, camera());
        let out = reference::render(&frame, 4, 9);
        prop_assert!(out.visibility.check_range().is_ok());
        let adj = EdgeAdjacency::build(&frame.scene.occluders());
        let s = adj.silhouette_from(light_at);
        prop_assert!(s.edges.iter().all(|e| e.a.is_finite() && e.b.is_finite()));
    }
}
