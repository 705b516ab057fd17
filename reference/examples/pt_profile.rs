//! Times the path tracer alone on a scene file, for profiling (`perf record`) and A/B
//! measurements of its inner loop without the rest of an experiment around it:
//!
//! ```text
//! cargo run --release -p reference --example pt_profile -- scenes/emissive_sphere.toml [spp] [repeats]
//! ```
//!
//! Prints, per repeat, the wall time of `render_image` (scene set-up included, as
//! `mitsuba_compare` times it), paths per second, and a hash of the image's bits, so that
//! a change meant to leave the estimator alone can be checked to be bit-identical.

use reference::pathtracer::TraceOptions;
use reference::pathtracer::camera::{RenderSettings, render_image_with};
use reference::pathtracer::contributions::Contributions;
use solvers::scene::SceneFile;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        return Err("usage: pt_profile <scene.toml> [spp] [repeats]".into());
    };
    let file = SceneFile::load(Path::new(path))?;
    let scene = file.scene;
    let spp = match args.get(2) {
        Some(s) => s.parse()?,
        None => scene.sampler.spp,
    };
    let repeats: usize = match args.get(3) {
        Some(s) => s.parse()?,
        None => 3,
    };
    let [w, h] = scene.camera.ok_or("the scene has no camera")?.resolution;
    let settings = RenderSettings {
        spp,
        seed: scene.sampler.seed,
        batches: 16,
        contributions: Contributions::all(),
    };
    let mut options = TraceOptions::of(&scene);
    if let Ok(b) = std::env::var("PT_BLOCK") {
        options.majorant_block = b.parse()?;
    }
    for _ in 0..repeats {
        let t0 = Instant::now();
        let image = render_image_with(&scene, &settings, &options)?;
        let seconds = t0.elapsed().as_secs_f64();
        let paths = (w * h) as f64 * spp as f64;
        // FNV-1a over the bits of every mean and standard error.
        let hash = image
            .mean
            .iter()
            .chain(&image.stderr)
            .fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
                (h ^ v.to_bits()).wrapping_mul(0x0100_0000_01b3)
            });
        let mean = image.mean.iter().sum::<f64>() / image.mean.len() as f64;
        println!(
            "{seconds:.4} s  {:.3} M paths/s  mean {mean:.6e}  bits {hash:016x}",
            paths / seconds / 1e6
        );
    }
    Ok(())
}
