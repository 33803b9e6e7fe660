//! Any bytes given as a glTF file (`.gltf` JSON or `.glb`): an error or a mesh whose indices are
//! in range and positions finite. External buffers resolve beside `fuzz/` (none exist there).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz/input.gltf");
    if let Ok(file) = shadowbench::scene::gltf::parse_gltf(data, path, None) {
        let mesh = file.mesh;
        let n = mesh.positions.len() as u32;
        assert!(mesh.triangles.iter().flatten().all(|&i| i < n));
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
    }
});
