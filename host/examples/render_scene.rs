//! Renders the textured pictures of a scenario (the video the OpenCV path tracks) as PNG files,
//! without OpenCV: `cargo run --release -p incise --example render_scene -- <scenario.toml>
//! <out-dir> [every]`.

use std::path::PathBuf;

use incise::generate::pipeline::simulate;
use incise::generate::texture::render_frame;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: render_scene <scenario.toml> <out-dir> [every]");
        std::process::exit(2);
    }
    let every: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1).max(1);
    let out = PathBuf::from(&args[2]);
    let result = simulate(&PathBuf::from(&args[1]), true).and_then(|sim| {
        std::fs::create_dir_all(&out)
            .map_err(|e| incise::generate::pipeline::GenError(e.to_string()))?;
        for f in (0..sim.positions.len()).step_by(every) {
            let path = out.join(format!("frame_{f:04}.png"));
            render_frame(&sim, f).save(&path).map_err(|e| {
                incise::generate::pipeline::GenError(format!("{}: {e}", path.display()))
            })?;
        }
        Ok(())
    });
    if let Err(e) = result {
        eprintln!("render_scene: {e}");
        std::process::exit(1);
    }
}
