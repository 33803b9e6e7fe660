//! Every wgpu run of a fixed set, written out so that two builds can be compared to the byte:
//! each registered algorithm with a wgpu execution, on its default options and each of its
//! option sets, on sphere-on-plane and torus-on-plane at 48×36 (map 128², tiles 16; the light
//! converted to the first kind the algorithm handles, as the registry parity tests do), and
//! sphere-on-plane under a rectangular light with a two-colour 4×4 checker texture where the
//! options honour one (and with [`TEXTURED`]'s options).
//!
//! For run `<id>-<k>-<scene>` (`k` 0 for the default options, then the option sets in order)
//! it writes `<run>.visibility` (the visibility buffer's f32 bytes), `<run>.rgb` when there is
//! one, and a line of `counters.txt`: every counter of the run and of each phase, in name
//! order, with its value's bits; the `pipeline.*` statistics included, times left out.
//!
//! Usage: `cargo run --release --example gpu_fingerprint -- OUT_DIR` (writes only under
//! OUT_DIR; fails without a wgpu adapter). `scripts/gpu-identical.sh` compares two builds.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;

use shadowbench::algorithms::{self, Backend, ExecContext, ALGORITHMS};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::light::LightKind;
use shadowbench::scene::LightTexture;

/// Options run under the textured light besides the default and the option sets.
const TEXTURED: &[(&str, &str)] = &[("soft_shadow_volume", r#"{"coverage": "texture"}"#)];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: gpu_fingerprint OUT_DIR")?,
    );
    std::fs::create_dir_all(&out)?;
    let mut lines = String::new();
    let scenes = ["sphere-on-plane", "torus-on-plane", "textured"];
    let mut runs = 0;
    for info in ALGORITHMS
        .iter()
        .filter(|i| i.backends.contains(&Backend::Wgpu))
    {
        let mut sets = vec![None];
        sets.extend(info.option_sets.iter().map(|s| Some(*s)));
        let textured_only = TEXTURED.iter().filter(|t| t.0 == info.id);
        sets.extend(textured_only.clone().map(|t| Some(t.1)));
        let first_textured_only = sets.len() - textured_only.count();
        for (k, set) in sets.iter().enumerate() {
            let mut ctx = ExecContext {
                reference_samples: 4,
                ..ExecContext::default()
            };
            if let Some(json) = set {
                ctx.options
                    .insert(info.id.to_string(), serde_json::from_str(json)?);
            }
            let scenes = match k >= first_textured_only {
                true => &scenes[2..],
                false => &scenes[..],
            };
            for &name in scenes {
                let textured = name == "textured";
                let rect = info.lights.contains(&LightKind::Rect);
                if textured
                    && (!rect || algorithms::check_light_texture(info.id, &ctx.options).is_err())
                {
                    continue;
                }
                let generator = if textured { "sphere-on-plane" } else { name };
                let mut scene = generators::find(generator)
                    .ok_or(generator)?
                    .build(&GeneratorParams::default());
                let kind = if textured {
                    LightKind::Rect
                } else {
                    info.lights[0]
                };
                scene.light = light_as(scene.light, kind, scene.bounds().center());
                if textured {
                    let checker = |i: u32, j: u32| match (i + j) % 2 {
                        0 => [1.0, 0.85, 0.2],
                        _ => [0.1, 0.3, 1.0],
                    };
                    scene.light_texture = Some(Arc::new(LightTexture::from_fn(4, 4, checker)));
                }
                let params = RunParams::of_scene(&scene, [48, 36], 128, 16);
                let frame = Frame::new(scene, params);
                let run = format!("{}-{k}-{name}", info.id);
                let o = match algorithms::run(info.id, Backend::Wgpu, &frame, &ctx) {
                    Ok(o) => o,
                    Err(e) => {
                        writeln!(lines, "{run} error: {e}")?;
                        continue;
                    }
                };
                let bytes: &[u8] = bytemuck::cast_slice(&o.visibility.data);
                std::fs::write(out.join(format!("{run}.visibility")), bytes)?;
                if let Some(rgb) = &o.rgb {
                    let bytes: &[u8] = bytemuck::cast_slice(&rgb.data);
                    std::fs::write(out.join(format!("{run}.rgb")), bytes)?;
                }
                write!(lines, "{run}")?;
                let phases = o
                    .phases
                    .iter()
                    .map(|p| (format!("{}:", p.name), &p.counters));
                for (what, c) in std::iter::once((String::new(), &o.counters)).chain(phases) {
                    for (key, v) in &c.0 {
                        write!(lines, " {what}{key}={:016x}", v.to_bits())?;
                    }
                }
                writeln!(lines)?;
                runs += 1;
            }
        }
    }
    std::fs::write(out.join("counters.txt"), lines)?;
    println!("{runs} wgpu runs written to {}", out.display());
    Ok(())
}
