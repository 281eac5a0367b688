//! `lgdm merge`: combine the trials of several run directories of one experiment into one run.
//!
//! Trial t of `lgdm train --trials N --seed S` uses seed S + t, so a 5-trial experiment can be
//! run as five `--trials 1 --seed k` runs (in parallel, on several machines, or across sessions)
//! and merged afterwards: the merged `metrics.json`, summary table and plots are those of the
//! 5-trial run. Runs are only merged when they are the same experiment: scenario, encoder (for
//! `--encoder ae`, the checkpoint's bytes), dataset, replay, epochs, evaluation settings and
//! every hyperparameter (the seed aside) must agree, and no seed may appear twice. Everything is checked before anything is written.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args as ClapArgs;

use crate::cmd::train::{METRICS_FORMAT_VERSION, RunConfig, write_atomic};
use crate::experiment::metrics::{RunMetrics, Summary, TrialRecord};
use crate::report;

/// Arguments of `lgdm merge`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Run directories written by `lgdm train` (each with metrics.json and config.toml).
    #[arg(required = true, num_args = 1..)]
    pub runs: Vec<PathBuf>,
    /// Output run directory (created if needed): metrics.json, config.toml, plots, summary.txt
    /// and links to the trials' models.
    #[arg(long)]
    pub out: PathBuf,
}

struct Run {
    dir: PathBuf,
    metrics: RunMetrics,
    config: RunConfig,
}

fn read_run(dir: &Path) -> Result<Run> {
    let mpath = dir.join("metrics.json");
    let text = std::fs::read_to_string(&mpath).with_context(|| {
        format!(
            "reading {} (is {} a finished run?)",
            mpath.display(),
            dir.display()
        )
    })?;
    let metrics: RunMetrics =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", mpath.display()))?;
    if metrics.format_version != METRICS_FORMAT_VERSION {
        bail!(
            "{} has format version {}, this lgdm reads version {}",
            mpath.display(),
            metrics.format_version,
            METRICS_FORMAT_VERSION
        );
    }
    let cpath = dir.join("config.toml");
    let text =
        std::fs::read_to_string(&cpath).with_context(|| format!("reading {}", cpath.display()))?;
    let config: RunConfig =
        toml::from_str(&text).with_context(|| format!("parsing {}", cpath.display()))?;
    Ok(Run {
        dir: dir.to_path_buf(),
        metrics,
        config,
    })
}

/// The first setting in which `b` differs from `a`, if any (seeds and trial counts may differ).
fn difference(a: &Run, b: &Run) -> Option<String> {
    let (ma, mb) = (&a.metrics, &b.metrics);
    let (ca, cb) = (&a.config, &b.config);
    macro_rules! same {
        ($name:literal, $x:expr, $y:expr) => {
            if $x != $y {
                return Some(format!("{}: {:?} vs {:?}", $name, $x, $y));
            }
        };
    }
    same!("scenario", ma.scenario, mb.scenario);
    same!("encoder", ma.encoder, mb.encoder);
    same!("dataset", ma.dataset, mb.dataset);
    same!("replay", ma.replay, mb.replay);
    same!("temporal context", ma.context, mb.context);
    same!("epochs", ma.epochs, mb.epochs);
    same!("categories", ma.categories, mb.categories);
    same!("eval_every", ca.eval_every, cb.eval_every);
    same!("eval_samples", ca.eval_samples, cb.eval_samples);
    same!("train_samples", ca.train_samples, cb.train_samples);
    same!("validate", ca.validate, cb.validate);
    // The checkpoint's bytes, not its path: a copy elsewhere is the same encoder.
    same!(
        "autoencoder checkpoint (FNV-1a)",
        ca.ae_checkpoint_fnv1a,
        cb.ae_checkpoint_fnv1a
    );
    let mut ga = ca.gdm.clone();
    let mut gb = cb.gdm.clone();
    ga.seed = 0;
    gb.seed = 0;
    if ga != gb {
        return Some("hyperparameters (config.toml [gdm]) differ".into());
    }
    None
}

/// The merged run: metrics and config, and each trial's model with its new trial index.
struct Merged {
    metrics: RunMetrics,
    config: RunConfig,
    models: Vec<(PathBuf, u64)>,
}

/// Checks the runs and merges them (trials sorted by seed).
fn merge(runs: &[Run]) -> Result<Merged> {
    let first = &runs[0];
    for r in &runs[1..] {
        if let Some(d) = difference(first, r) {
            bail!(
                "{} and {} are different experiments ({d}); only runs of one experiment merge",
                first.dir.display(),
                r.dir.display()
            );
        }
    }
    // (seed, run index, trial record)
    let mut all: Vec<(u64, usize, TrialRecord)> = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        for t in &r.metrics.trials {
            if let Some((_, j, _)) = all.iter().find(|(s, _, _)| *s == t.seed) {
                bail!(
                    "seed {} appears in both {} and {}: the same trial twice would count double",
                    t.seed,
                    runs[*j].dir.display(),
                    r.dir.display()
                );
            }
            all.push((t.seed, i, t.clone()));
        }
    }
    all.sort_by_key(|(s, _, _)| *s);
    let mut models = Vec::new();
    let mut trials = Vec::new();
    for (new_index, (_, i, mut t)) in all.into_iter().enumerate() {
        let model = runs[i].dir.join(format!("model-trial{}.lgdm", t.trial));
        models.push((model, new_index as u64));
        t.trial = new_index;
        trials.push(t);
    }
    let seed = trials[0].seed;
    let summary = Summary::of(&trials);
    let metrics = RunMetrics {
        seed,
        trials,
        summary,
        ..first.metrics.clone()
    };
    let mut config = first.config.clone();
    config.trials = metrics.trials.len();
    config.seed = seed;
    config.gdm.seed = seed;
    Ok(Merged {
        metrics,
        config,
        models,
    })
}

/// Runs `lgdm merge`.
pub fn run(args: Args) -> Result<()> {
    let runs = args
        .runs
        .iter()
        .map(|d| read_run(d))
        .collect::<Result<Vec<_>>>()?;
    let Merged {
        metrics,
        config,
        models,
    } = merge(&runs)?;
    let seeds: Vec<u64> = metrics.trials.iter().map(|t| t.seed).collect();
    if seeds.windows(2).any(|w| w[1] != w[0] + 1) {
        eprintln!(
            "note: the seeds {seeds:?} are not consecutive; the merged run is not the same as one \
             `lgdm train --trials {}` run",
            seeds.len()
        );
    }
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    write_atomic(
        &out.join("config.toml"),
        toml::to_string_pretty(&config)?.as_bytes(),
    )?;
    write_atomic(
        &out.join("metrics.json"),
        serde_json::to_string_pretty(&metrics)?.as_bytes(),
    )?;
    crate::plot::write_run_plots(out, &metrics).context("drawing the plots")?;
    let table = report::summary_table(&metrics);
    write_atomic(&out.join("summary.txt"), table.as_bytes())?;
    let mut missing = 0;
    for (src, t) in &models {
        let dst = out.join(format!("model-trial{t}.lgdm"));
        if !src.exists() {
            missing += 1;
            continue;
        }
        let _ = std::fs::remove_file(&dst);
        if std::fs::hard_link(src, &dst).is_err() {
            std::fs::copy(src, &dst)
                .with_context(|| format!("copying {} to {}", src.display(), dst.display()))?;
        }
    }
    if missing > 0 {
        eprintln!(
            "note: {missing} trial model(s) were not found next to their metrics.json and are not linked"
        );
    }
    println!("{table}");
    println!(
        "merged {} run(s), {} trial(s), seeds {seeds:?}: {}",
        runs.len(),
        metrics.trials.len(),
        out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::metrics::Figures;

    fn figures(a: f64) -> Figures {
        Figures {
            n: 10,
            instance_accuracy: a,
            category_accuracy_em: a,
            category_accuracy_sm: a,
        }
    }

    fn run(dir: &str, seeds: &[u64], replay: bool) -> Run {
        let trials: Vec<TrialRecord> = seeds
            .iter()
            .enumerate()
            .map(|(i, &s)| TrialRecord {
                trial: i,
                seed: s,
                held_out_instances: vec![],
                step_labels: vec!["a".into()],
                steps: vec![],
                test: figures(0.5 + s as f64 / 10.0),
                test_no_context: figures(0.5),
                new_instance: None,
                per_category_test_accuracy: vec![],
                episodic_nodes: 10,
                semantic_nodes: 5,
                model_size_bytes: 1000,
                inference_ms_per_sample: 0.1,
                train_seconds: 1.0,
            })
            .collect();
        let summary = Summary::of(&trials);
        let metrics = RunMetrics {
            format_version: METRICS_FORMAT_VERSION,
            scenario: "ni".into(),
            encoder: "good".into(),
            dataset: "/d".into(),
            seed: seeds[0],
            replay,
            context: true,
            epochs: 1,
            categories: vec!["mug".into()],
            trials,
            summary,
        };
        let config = RunConfig {
            scenario: crate::experiment::scenario::Scenario::Ni,
            encoder: "good".into(),
            dataset: "/d".into(),
            trials: seeds.len(),
            seed: seeds[0],
            replay,
            epochs: 1,
            eval_every: 1,
            eval_samples: 3000,
            train_samples: 0,
            validate: false,
            hyperparameters_from: "preset".into(),
            ae_checkpoint: None,
            ae_checkpoint_fnv1a: None,
            gdm: lgdm_gdm::GdmConfig {
                seed: seeds[0],
                ..Default::default()
            },
        };
        Run {
            dir: dir.into(),
            metrics,
            config,
        }
    }

    #[test]
    fn merges_trials_in_seed_order_and_summarises_all() {
        let Merged {
            metrics: m,
            config: c,
            models,
        } = merge(&[run("b", &[2, 3], true), run("a", &[0, 1], true)]).unwrap();
        let seeds: Vec<u64> = m.trials.iter().map(|t| t.seed).collect();
        assert_eq!(seeds, [0, 1, 2, 3]);
        assert_eq!(m.summary.trials, 4);
        assert!((m.summary.test_category_accuracy_sm.mean - 0.65).abs() < 1e-12);
        assert_eq!((c.trials, c.seed, m.seed), (4, 0, 0));
        assert_eq!(models[0].0, Path::new("a").join("model-trial0.lgdm"));
        assert_eq!(models[2].0, Path::new("b").join("model-trial0.lgdm"));
        assert_eq!(models[3].1, 3);
    }

    #[test]
    fn refuses_different_experiments_and_duplicate_seeds() {
        let err = |runs: &[Run]| merge(runs).err().expect("refused").to_string();
        let e = err(&[run("a", &[0], true), run("b", &[1], false)]);
        assert!(e.to_string().contains("replay"), "{e}");
        let e = err(&[run("a", &[0, 1], true), run("b", &[1], true)]);
        assert!(e.to_string().contains("seed 1"), "{e}");
        let mut other = run("c", &[5], true);
        other.config.gdm.episodic.activation_threshold = 0.9;
        let e = err(&[run("a", &[0], true), other]);
        assert!(e.to_string().contains("hyperparameters"), "{e}");
    }

    fn ae_run(dir: &str, seed: u64, path: &str, hash: &str) -> Run {
        let mut r = run(dir, &[seed], true);
        r.metrics.encoder = "ae".into();
        r.config.encoder = "ae".into();
        r.config.ae_checkpoint = Some(path.into());
        r.config.ae_checkpoint_fnv1a = Some(hash.into());
        r
    }

    #[test]
    fn autoencoder_runs_merge_only_with_the_same_checkpoint_bytes() {
        let e = merge(&[
            ae_run("a", 0, "/x/cpu.pt", "00000000000000aa"),
            ae_run("b", 1, "/x/cpu.pt", "00000000000000bb"),
        ])
        .err()
        .expect("refused")
        .to_string();
        assert!(e.contains("checkpoint"), "{e}");
        // Same bytes under another path merge, and the merged config keeps the checkpoint.
        let m = merge(&[
            ae_run("a", 0, "/x/cpu.pt", "00000000000000aa"),
            ae_run("b", 1, "/y/copy.pt", "00000000000000aa"),
        ])
        .unwrap();
        assert_eq!(m.config.ae_checkpoint.as_deref(), Some("/x/cpu.pt"));
        assert_eq!(
            m.config.ae_checkpoint_fnv1a.as_deref(),
            Some("00000000000000aa")
        );
        let text = toml::to_string_pretty(&m.config).unwrap();
        assert!(
            text.contains("ae_checkpoint_fnv1a = \"00000000000000aa\""),
            "{text}"
        );
    }
}
