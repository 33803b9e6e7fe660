//! Any bytes given as a machine configuration: an error or a valid machine whose modelled
//! caches can be sized without overflow, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use shadowbench::model::cache::CoreCaches;
use shadowbench::model::MachineConfig;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let path = std::path::Path::new("fuzz/machine.json");
        if let Ok(m) = MachineConfig::from_json(text, path) {
            // What the memory estimate of a cpu-model run reads.
            let per_core = CoreCaches::bytes(&m);
            assert!(per_core > 0);
            let _ = m.describe();
            // Small configurations are built for real, as a run would.
            if per_core.saturating_mul(u64::from(m.cores)) <= 64 << 20 {
                let mut c = CoreCaches::new(&m);
                for line in 0..64 {
                    c.access(line * 7, line % 3 == 0);
                }
            }
        }
    }
});
