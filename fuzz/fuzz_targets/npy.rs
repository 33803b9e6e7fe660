//! Any bytes given as a `.npy` visibility array and as a mask: an error, or a row-major array
//! whose size matches its shape (each side 1..=16384) and, for visibility, values in [0, 1].
#![no_main]

use libfuzzer_sys::fuzz_target;
use shadowbench::util::npy::parse_2d;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz/input.npy");
    if let Ok(a) = parse_2d::<f32>(data, path, "visibility array", "float32") {
        assert_eq!(a.data.len(), a.width as usize * a.height as usize);
        assert!(a.width >= 1 && a.height >= 1 && a.width <= 16384 && a.height <= 16384);
        let v = shadowbench::visibility::VisibilityBuffer {
            width: a.width,
            height: a.height,
            data: a.data,
        };
        let _ = v.check_range();
    }
    if let Ok(a) = parse_2d::<u8>(data, path, "mask", "uint8") {
        assert_eq!(a.data.len(), a.width as usize * a.height as usize);
    }
});
