//! `odocal train`: trains the odometry corrector (18-k-2 perceptron) on dataset.json, or
//! sweeps hidden sizes with k-fold cross-validation over restarts and writes Tables 1 and 2.

use std::collections::HashMap;
use std::path::PathBuf;

use anyhow::{bail, Context};
use odocal_dataset::OracleFile;
use odocal_trainer::crossval::{assign_folds, capacity_warning, derive_seed};
use odocal_trainer::{
    report, sweep, train, KinematicCalibration, Method, Metrics, ModelFile, ModelMetrics,
    SweepSettings, TrainSettings,
};

use crate::output::{progress, write_atomic, write_json};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// The training set (dataset.json from `odocal dataset`).
    pub dataset: PathBuf,
    /// Where to write the trained model (model.json); required unless --sweep is given.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Hidden neurons k (the source chose 8).
    #[arg(long, default_value_t = 8)]
    pub hidden: usize,
    /// Training method: lm (Levenberg–Marquardt, the levenberg-marquardt crate) or backprop.
    #[arg(long, default_value = "lm")]
    pub method: String,
    /// Random seed (initial weights, validation split, folds).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sweep hidden sizes A..B (inclusive) with cross-validation instead of training one model.
    #[arg(long)]
    pub sweep: Option<String>,
    /// Random restarts per hidden size in a sweep.
    #[arg(long, default_value_t = 10)]
    pub restarts: usize,
    /// Folds of the cross-validation (also used for the single model's estimate).
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Directory for the sweep report (report.json, report.md).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Truth of a synthetic experiment (truth/oracle.json): adds the oracle row to Table 2.
    #[arg(long)]
    pub oracle: Option<PathBuf>,
    /// Weight decay in normalised units (0 disables it).
    #[arg(long)]
    pub weight_decay: Option<f64>,
    /// Fraction of the training samples held out for early stopping (0 disables it).
    #[arg(long)]
    pub val_fraction: Option<f64>,
    /// Upper bound on training epochs.
    #[arg(long)]
    pub max_epochs: Option<usize>,
    /// Early stopping: epochs without validation improvement before stopping
    /// (default 2 for lm, 200 for backprop).
    #[arg(long)]
    pub max_fail: Option<usize>,
    /// Early stopping: smallest relative decrease of the validation error that counts as
    /// an improvement (default 0.03 for lm, 0 for backprop).
    #[arg(long)]
    pub min_improvement: Option<f64>,
}

fn parse_range(s: &str) -> anyhow::Result<Vec<usize>> {
    let bad = || anyhow::anyhow!("--sweep '{s}': expected A..B with whole numbers, e.g. 6..12");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let b = b.strip_prefix('=').unwrap_or(b);
    let a: usize = a.trim().parse().map_err(|_| bad())?;
    let b: usize = b.trim().parse().map_err(|_| bad())?;
    if a > b {
        bail!("--sweep '{s}': the range is empty (A > B)");
    }
    Ok((a..=b).collect())
}

fn settings(args: &Args) -> anyhow::Result<TrainSettings> {
    let method: Method = args.method.parse()?;
    let mut s = TrainSettings::new(args.hidden, method);
    if let Some(v) = args.weight_decay {
        s.weight_decay = v;
    }
    if let Some(v) = args.val_fraction {
        s.val_fraction = v;
    }
    if let Some(v) = args.max_epochs {
        s.max_epochs = v;
    }
    if let Some(v) = args.max_fail {
        s.max_fail = v;
    }
    if let Some(v) = args.min_improvement {
        s.min_improvement = v;
    }
    s.validate()?;
    Ok(s)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let bytes = std::fs::read(&args.dataset)
        .with_context(|| format!("cannot read {}", args.dataset.display()))?;
    let (ds, sha) = odocal_trainer::parse_dataset(&bytes, &args.dataset.display().to_string())?;
    let ts = settings(&args)?;
    let oracle = match &args.oracle {
        Some(p) => {
            let o = OracleFile::read(p)?;
            let mut map = HashMap::new();
            for s in &ds.samples {
                let end = o.end_m(s).with_context(|| {
                    format!(
                        "{}: no entry for run '{}' of the dataset",
                        p.display(),
                        s.run_id
                    )
                })?;
                map.insert(s.run_id.clone(), end);
            }
            Some(map)
        }
        None => None,
    };

    if let Some(range) = &args.sweep {
        let sizes = parse_range(range)?;
        let settings = SweepSettings {
            hidden_sizes: sizes.clone(),
            restarts: args.restarts,
            folds: args.folds,
            train: ts,
            seed: args.seed,
        };
        let bar = progress(
            (sizes.len() * args.restarts * args.folds) as u64,
            "training",
        );
        let rep = sweep(&ds, &sha, &settings, oracle.as_ref(), &|| bar.inc(1))
            .with_context(|| format!("{}", args.dataset.display()))?;
        bar.finish_and_clear();
        for w in &rep.warnings {
            eprintln!("odocal: warning: {w}");
        }
        let md = report::markdown(&rep);
        println!("{md}");
        if let Some(dir) = &args.report {
            write_json(&dir.join("report.json"), &rep)?;
            write_atomic(&dir.join("report.md"), md.as_bytes())?;
            eprintln!(
                "wrote {} and {}",
                dir.join("report.json").display(),
                dir.join("report.md").display()
            );
        }
        if let Some(out) = &args.out {
            eprintln!(
                "odocal: note: --out is ignored with --sweep; train the chosen k without --sweep"
            );
            let _ = out;
        }
        return Ok(());
    }

    let Some(out) = &args.out else {
        bail!("give --out model.json to train a model, or --sweep A..B to cross-validate hidden sizes");
    };
    let n = ds.samples.len();
    let n_fit =
        n - ((n as f64 * ts.val_fraction).round() as usize).max(usize::from(ts.val_fraction > 0.0));
    if let Some(w) = capacity_warning(ts.hidden, n_fit) {
        eprintln!("odocal: warning: {w}");
    }
    let inputs: Vec<Vec<f64>> = ds.samples.iter().map(|s| s.inputs.clone()).collect();
    let targets: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.target_m).collect();
    let net = train(&inputs, &targets, &ts, args.seed)
        .with_context(|| format!("{}", args.dataset.display()))?;
    let all: Vec<&odocal_dataset::Sample> = ds.samples.iter().collect();
    let pred: Vec<[f64; 2]> = inputs.iter().map(|x| net.predict(x)).collect();
    let raw: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.raw_end_m).collect();

    // Fit and early-stopping validation samples reported separately.
    let subset = |idx: &[usize]| {
        let s: Vec<&odocal_dataset::Sample> = idx.iter().map(|&i| &ds.samples[i]).collect();
        let p: Vec<[f64; 2]> = idx.iter().map(|&i| pred[i]).collect();
        Metrics::of(&s, &p)
    };
    let train_metrics = subset(&net.fit_indices);
    let validation = (!net.validation_indices.is_empty()).then(|| subset(&net.validation_indices));
    // Cross-validated estimate of this configuration: one restart over the folds.
    let cross_validated = match assign_folds(&ds.samples, args.folds, args.seed) {
        Ok(_) => {
            let s = SweepSettings {
                hidden_sizes: vec![ts.hidden],
                restarts: 1,
                folds: args.folds,
                train: ts.clone(),
                seed: derive_seed(args.seed, &[0xC0]),
            };
            let bar = progress(args.folds as u64, "cross-val");
            let rep = sweep(&ds, &sha, &s, oracle.as_ref(), &|| bar.inc(1))?;
            bar.finish_and_clear();
            let md = report::table2_markdown(&rep);
            println!("{md}");
            let name = odocal_trainer::crossval::net_method_name(ts.hidden);
            let r = odocal_trainer::crossval::row(&rep.table2, &name)
                .context("cross-validation lost its row")?;
            Some(Metrics {
                mse_m2: r.mse_m2.mean,
                mse_cm2: r.mse_m2.mean * 1e4,
                half_sse_m2: r.mse_m2.mean * n as f64,
                rel_error: r.rel_error.mean,
                rms_end_error_m: r.rms_end_error_m,
                n,
            })
        }
        Err(e) => {
            eprintln!("odocal: warning: no cross-validated estimate ({e})");
            None
        }
    };
    let kin = KinematicCalibration::fit(&all, &ds.robot).ok();
    let metrics = ModelMetrics {
        train: train_metrics,
        validation,
        raw_odometry: Metrics::of(&all, &raw),
        cross_validated,
    };
    let model = ModelFile::new(&net, &ts, args.seed, ds.robot, &sha, n, metrics, kin);
    write_json(out, &model)?;
    println!(
        "trained 18-{}-2 ({} parameters) with {:?} on {} samples ({} fitted): kept epoch {} ({}).",
        ts.hidden,
        net.net.n_params(),
        ts.method,
        n,
        net.n_fit,
        net.best_epoch,
        net.stop_reason
    );
    println!(
        "fitted samples: MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} % (raw odometry on all samples {:.2} %).",
        model.metrics.train.mse_m2,
        model.metrics.train.mse_cm2,
        100.0 * model.metrics.train.rel_error,
        100.0 * model.metrics.raw_odometry.rel_error
    );
    if let Some(v) = &model.metrics.validation {
        println!(
            "early-stopping split ({} samples): MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} %.",
            v.n,
            v.mse_m2,
            v.mse_cm2,
            100.0 * v.rel_error
        );
    }
    if let Some(cv) = &model.metrics.cross_validated {
        println!(
            "cross-validated ({} folds): MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} %.",
            args.folds,
            cv.mse_m2,
            cv.mse_cm2,
            100.0 * cv.rel_error
        );
    }
    if let Some(k) = &model.kinematic_calibration {
        println!(
            "kinematic calibration: left_wheel_radius_multiplier {:.4}, right_wheel_radius_multiplier {:.4}, wheel_separation_multiplier {:.4}",
            k.ros.left_wheel_radius_multiplier, k.ros.right_wheel_radius_multiplier, k.ros.wheel_separation_multiplier
        );
    }
    println!("wrote {}", out.display());
    Ok(())
}
