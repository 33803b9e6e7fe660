//! Any bytes given as a PLY file (ASCII or binary): an error or a mesh whose indices are in
//! range and positions finite.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz/input.ply");
    if let Ok(file) = shadowbench::scene::ply::parse_ply(data.to_vec(), path) {
        let mesh = file.mesh;
        let n = mesh.positions.len() as u32;
        assert!(mesh.triangles.iter().flatten().all(|&i| i < n));
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
    }
});
