//! Times one intrinsic replay of a saved model (for example a `model-trial0.lgdm` that
//! `lgdm train` wrote) and saves the replayed model, so two builds can be compared on real
//! features, for speed and for identical bytes:
//!
//! ```text
//! cargo run --release -p lgdm-gdm --example replay_time -- RUN/model-trial0.lgdm OUT.lgdm
//! ```

use std::path::PathBuf;
use std::time::Instant;

use lgdm_gdm::Gdm;

fn main() {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [model, out] = &args[..] else {
        eprintln!("usage: replay_time MODEL.lgdm OUT.lgdm");
        std::process::exit(2);
    };
    let mut gdm = Gdm::load(model).unwrap_or_else(|e| {
        eprintln!("error: {}: {e}", model.display());
        std::process::exit(1);
    });
    let (em, sm) = (gdm.episodic().len(), gdm.semantic().len());
    let start = Instant::now();
    let stats = gdm.replay().unwrap_or_else(|e| {
        eprintln!("error: replay: {e}");
        std::process::exit(1);
    });
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "G-EM {em} / G-SM {sm} nodes: {} pseudo-samples replayed in {seconds:.2} s ({:.0} µs each)",
        stats.samples,
        1e6 * seconds / stats.samples.max(1) as f64
    );
    if let Err(e) = gdm.save(out) {
        eprintln!("error: {}: {e}", out.display());
        std::process::exit(1);
    }
}
