//! Any bytes given as a scenario file: an error or a valid scenario, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let path = std::path::Path::new("fuzz/scenario.json");
        if let Ok(loaded) = shadowbench::scenario::Loaded::from_str(text, path) {
            // Expanding the sweep of any accepted scenario must work too (or be refused for
            // its size, before anything is allocated).
            let _ = loaded.cases(10_000);
        }
    }
});
