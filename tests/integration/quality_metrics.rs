//! The region metrics (`mae_penumbra`, `umbra_error`, `lit_error`) on the exact-answer plate of
//! the D-buffer tests: a straight plate edge under a horizontal disc, whose visibility on the
//! ground and whose umbra, penumbra and lit regions follow from similar triangles.

use shadowbench::algorithms::Backend;
use shadowbench::metrics::{compare, SHADOW_THRESHOLD, UMBRA_THRESHOLD};
use shadowbench::visibility::VisibilityBuffer;

use super::dbuffer::{
    edge_under_tilted_disc, exact_visibility, frame, run, PLATE_THICKNESS, PLATE_TOP,
    TILTED_CENTRE, TILTED_RADIUS,
};

/// Where a ground point `(x, 0, z)` lies under the horizontal disc (centre `TILTED_CENTRE`,
/// radius `TILTED_RADIUS`) past the plate `x < 0` of [`edge_under_tilted_disc`], in 2D: the ray
/// to a disc point of abscissa `d` crosses the plate's edge height `e` (its top beside the
/// plate, its bottom under it) at `x + (d − x)·e/c_y`, and passes when that is ≥ 0, i.e. when
/// `d ≥ t = x·(1 − c_y/e)`. The point is lit when `t` is at or left of the disc, in umbra when
/// `t` is at or right of it, in penumbra between; its visibility is the circular segment of the
/// disc right of `t`. Returns (region, visibility): region −1 umbra, 0 penumbra, 1 lit.
fn by_similar_triangles(x: f32) -> (i8, f64) {
    let e = if x >= 0.0 {
        PLATE_TOP
    } else {
        PLATE_TOP - PLATE_THICKNESS
    };
    let (c, r) = (TILTED_CENTRE, TILTED_RADIUS);
    let t = (x * (1.0 - c.y / e)) as f64;
    let u = (t - c.x as f64) / r as f64;
    if u <= -1.0 {
        (1, 1.0)
    } else if u >= 1.0 {
        (-1, 0.0)
    } else {
        (
            0,
            (u.acos() - u * (1.0 - u * u).sqrt()) / std::f64::consts::PI,
        )
    }
}

/// `mae_penumbra`, `umbra_error` and `lit_error` of pcss and of the hard shadow map against the
/// exact answer equal the same figures computed over the regions that the geometry gives,
/// and the exact answer of the D-buffer tests agrees with the similar triangles.
#[test]
fn region_metrics_on_the_exact_answer_plate_match_the_geometry() {
    let scene = edge_under_tilted_disc(0.0, true);
    let f = frame(scene, [64, 48], 512);
    let n = f.gbuffer.triangle.len();
    let ground: Vec<bool> = (0..n)
        .map(|i| {
            f.gbuffer.is_hit(i) && f.flat.object_of_triangle[f.gbuffer.triangle[i] as usize] == 0
        })
        .collect();
    let geometry: Vec<(i8, f64)> = (0..n)
        .map(|i| by_similar_triangles(f.gbuffer.position[i].x))
        .collect();
    let exact = VisibilityBuffer {
        width: f.gbuffer.width,
        height: f.gbuffer.height,
        data: (0..n)
            .map(|i| {
                if ground[i] {
                    exact_visibility(f.gbuffer.position[i], glam::Vec3::NEG_Y)
                } else {
                    1.0
                }
            })
            .collect(),
    };
    // The two derivations of the answer agree (to f32 rounding).
    for i in (0..n).filter(|&i| ground[i]) {
        let d = (exact.data[i] as f64 - geometry[i].1).abs();
        assert!(
            d < 1e-4,
            "pixel {i}: {} against {}",
            exact.data[i],
            geometry[i].1
        );
    }
    // The regions as the metrics define them, from the visibility by similar triangles: a
    // pixel of the geometric penumbra within half a sample of 1024 of lit or of umbra counts
    // as lit or umbra (a sliver at each side of the penumbra).
    let slivers = (0..n)
        .filter(|&i| ground[i] && geometry[i].0 == 0)
        .filter(|&i| !(UMBRA_THRESHOLD as f64..SHADOW_THRESHOLD as f64).contains(&geometry[i].1))
        .count();
    let geometry: Vec<(i8, f64)> = geometry
        .into_iter()
        .map(|(_, v)| {
            let k = if v < UMBRA_THRESHOLD as f64 {
                -1
            } else if v >= SHADOW_THRESHOLD as f64 {
                1
            } else {
                0
            };
            (k, v)
        })
        .collect();
    let count = |k: i8| (0..n).filter(|&i| ground[i] && geometry[i].0 == k).count();
    assert!(
        slivers * 50 < count(0),
        "{slivers} of {} in the slivers",
        count(0)
    );
    assert!(count(0) >= 40, "{} penumbra pixels", count(0));
    assert!(count(1) >= 40, "{} lit pixels", count(1));
    for id in ["pcss", "hard_shadow_map"] {
        let v = run(id, Backend::CpuNative, &f).visibility;
        let m = compare(&v, &exact, &ground);
        let (ground, geometry) = (&ground, &geometry);
        let over = |k: i8| (0..n).filter(move |&i| ground[i] && geometry[i].0 == k);
        let penumbra: Vec<f64> = over(0)
            .map(|i| (v.data[i] as f64 - geometry[i].1).abs())
            .collect();
        let mae_penumbra = penumbra.iter().sum::<f64>() / penumbra.len() as f64;
        assert_eq!(m.penumbra_pixels as usize, penumbra.len(), "{id}");
        assert!(
            (m.mae_penumbra.unwrap() - mae_penumbra).abs() < 1e-5,
            "{id}: mae_penumbra {:?}, by geometry {mae_penumbra}",
            m.mae_penumbra
        );
        let lit_shadowed = over(1).filter(|&i| v.data[i] < SHADOW_THRESHOLD).count();
        assert_eq!(m.lit_pixels as usize, count(1), "{id}");
        assert_eq!(
            m.lit_error,
            Some(lit_shadowed as f64 / count(1) as f64),
            "{id}"
        );
        let umbra = count(-1);
        assert_eq!(m.umbra_pixels as usize, umbra, "{id}");
        let leaks = over(-1).filter(|&i| v.data[i] >= UMBRA_THRESHOLD).count();
        assert_eq!(
            m.umbra_error,
            (umbra > 0).then(|| leaks as f64 / umbra as f64),
            "{id}"
        );
        eprintln!(
            "{id}: {} penumbra px, mae_penumbra {mae_penumbra:.5}; {} lit px, lit_error {:?}; \
             {umbra} umbra px, umbra_error {:?}",
            penumbra.len(),
            count(1),
            m.lit_error,
            m.umbra_error
        );
    }
}
