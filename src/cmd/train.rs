//! `odocal train`: trains the odometry corrector (18-k-2 perceptron) on dataset.json, or
//! sweeps hidden sizes with k-fold cross-validation over restarts and writes Tables 1 and 2.

use std::collections::HashMap;
use std::path::PathBuf;

use anyhow::{bail, Context};
use odocal_dataset::{Dataset, OracleFile};
use odocal_trainer::train::HIDDEN_RANGE;
use odocal_trainer::{
    fit_model, oracle_ends, report, sweep, Method, PathModelFile, SweepSettings, TrainSettings,
};

use crate::output::{
    check_output_dir, check_output_file, commit, count, progress, write_atomic, write_json,
};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// The training set (dataset.json from `odocal dataset`).
    pub dataset: PathBuf,
    /// Where to write the trained model (model.json); required unless --sweep is given, and
    /// refused with it (a sweep writes no model).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Hidden neurons k (default: 8 for straight runs, as the source chose; 2 for a path
    /// model trained on windows). A sweep takes its sizes from --sweep instead.
    #[arg(long)]
    pub hidden: Option<usize>,
    /// Training method: lm (Levenberg–Marquardt, the levenberg-marquardt crate; the default)
    /// or backprop.
    #[arg(long)]
    pub method: Option<String>,
    /// Random seed (initial weights, validation split, folds).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sweep hidden sizes A..B (inclusive) with cross-validation instead of training one model.
    #[arg(long)]
    pub sweep: Option<String>,
    /// Random restarts per hidden size in a sweep (default 10).
    #[arg(long)]
    pub restarts: Option<usize>,
    /// Folds of the cross-validation (also used for the single model's estimate; default 5).
    #[arg(long)]
    pub folds: Option<usize>,
    /// Fit the one model without the cross-validated estimate of its error (faster; model.json
    /// then records no cross-validated figures).
    #[arg(long)]
    pub no_cv: bool,
    /// Directory for the sweep report (report.json, report.md); with --sweep only.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Truth of a synthetic experiment (truth/oracle.json): adds the oracle row to Table 2.
    #[arg(long)]
    pub oracle: Option<PathBuf>,
    /// Weight decay in normalised units (0 disables it) [default: 0].
    #[arg(long)]
    pub weight_decay: Option<f64>,
    /// Fraction of the training samples held out for early stopping (0 disables it)
    /// [default: 0.15].
    #[arg(long)]
    pub val_fraction: Option<f64>,
    /// Upper bound on training epochs [default: 200 for lm, 20000 for backprop].
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

/// Fewest recordings a path model is fitted to without a warning: the windows of one
/// recording overlap (10 s windows every 5 s) and share one floor and one tour.
const MIN_PATH_RECORDINGS: usize = 3;

/// Restarts of a path model's fit (its first starts from the kinematic fit, so few suffice).
const PATH_RESTARTS: usize = 2;
/// Random restarts per hidden size in a sweep.
const DEFAULT_RESTARTS: usize = 10;
/// Folds of the cross-validation.
const DEFAULT_FOLDS: usize = 5;

/// The options given that a path model's fit does not use: it is one Levenberg–Marquardt fit
/// of the chained windows, judged afterwards by `odocal evaluate`, so the perceptron's
/// training settings and the cross-validation have nothing to act on.
fn unused_for_paths(args: &Args) -> Vec<&'static str> {
    [
        ("--sweep", args.sweep.is_some()),
        ("--report", args.report.is_some()),
        ("--oracle", args.oracle.is_some()),
        ("--method", args.method.is_some()),
        ("--restarts", args.restarts.is_some()),
        ("--folds", args.folds.is_some()),
        ("--no-cv", args.no_cv),
        ("--weight-decay", args.weight_decay.is_some()),
        ("--val-fraction", args.val_fraction.is_some()),
        ("--max-epochs", args.max_epochs.is_some()),
        ("--max-fail", args.max_fail.is_some()),
        ("--min-improvement", args.min_improvement.is_some()),
    ]
    .into_iter()
    .filter_map(|(name, given)| given.then_some(name))
    .collect()
}

/// Refuses straight-run options that another option given beside them leaves without effect:
/// a sweep cross-validates every size of its range and writes no model, one model fitted
/// with --no-cv makes no folds and no Table 2, and --val-fraction 0 holds out no validation
/// samples, so early stopping has no error to watch. Ignored, they would leave the user
/// believing they had set something (model.json records them as set).
fn refuse_unused_combinations(args: &Args) -> anyhow::Result<()> {
    if args.val_fraction == Some(0.0) && args.no_cv {
        // Nothing would stop the fit, nor say how it does on runs it has not seen: trained so
        // on the demo's 131 runs it "fitted" 0.62 % and put a fresh run 0.78 m off, where
        // raw odometry was 0.21 m off.
        bail!(
            "--val-fraction 0 with --no-cv: the model would have neither early stopping nor an error measured on runs it was not fitted to, and a perceptron fitted to the last epoch learns the runs by heart; leave out --no-cv to have its error cross-validated, or give --val-fraction above 0 (default 0.15)"
        );
    }
    if args.val_fraction == Some(0.0) {
        let stopping: Vec<String> = [
            args.max_fail.map(|n| format!("--max-fail {n}")),
            args.min_improvement
                .map(|v| format!("--min-improvement {v}")),
        ]
        .into_iter()
        .flatten()
        .collect();
        if !stopping.is_empty() {
            bail!(
                "{} with --val-fraction 0: --val-fraction 0 turns early stopping off (no validation samples), so training stops only at --max-epochs or when the fit converges; leave {} out, or give --val-fraction above 0 (default 0.15) to stop early",
                stopping.join(" and "),
                if stopping.len() == 1 { "it" } else { "them" }
            );
        }
    }
    match &args.sweep {
        Some(range) => {
            if let Some(k) = args.hidden {
                bail!("--hidden {k} with --sweep {range}: a sweep trains every hidden size of its range; leave out --hidden (--sweep {k}..{k} sweeps k = {k} alone), or --sweep to train the one model");
            }
            if args.no_cv {
                bail!("--no-cv with --sweep {range}: a sweep is cross-validation; leave out --no-cv, or --sweep to fit the one model without the estimate");
            }
            if let Some(out) = &args.out {
                bail!("--out {} with --sweep {range}: a sweep writes no model (Tables 1 and 2 go to --report); leave out --out, and train the chosen k without --sweep", out.display());
            }
        }
        None => {
            if args.restarts.is_some() {
                bail!("--restarts is used by --sweep only (the one model of --out is trained once); leave it out, or add --sweep A..B");
            }
            if let Some(dir) = &args.report {
                bail!("--report {} without --sweep: only a sweep writes report.json and report.md (the one model's figures are printed and kept in model.json); leave out --report, or add --sweep A..B", dir.display());
            }
            if args.no_cv {
                if let Some(n) = args.folds {
                    bail!("--folds {n} with --no-cv: --no-cv fits the one model without cross-validation, so there are no folds; leave out --folds, or --no-cv to have the cross-validated estimate");
                }
                if let Some(p) = &args.oracle {
                    bail!("--oracle {} with --no-cv: the oracle is a row of the cross-validated Table 2, which --no-cv leaves out; leave out --oracle, or --no-cv", p.display());
                }
            }
        }
    }
    Ok(())
}

/// Trains the path corrector on a window dataset.
fn run_paths(args: &Args, ds: &Dataset, sha: &str) -> anyhow::Result<()> {
    let unused = unused_for_paths(args);
    if !unused.is_empty() {
        bail!(
            "{}: a window dataset trains a path model, which takes only --out, --hidden and --seed; {} {} not used for a path model ({} to straight-run datasets; judge a path model with `odocal evaluate`)",
            args.dataset.display(),
            unused.join(", "),
            if unused.len() == 1 { "is" } else { "are" },
            if unused.len() == 1 { "it belongs" } else { "they belong" }
        );
    }
    let Some(out) = &args.out else {
        bail!("give --out path-model.json to train a path model");
    };
    let hidden = args.hidden.unwrap_or(2);
    if hidden > 16 {
        bail!("--hidden {hidden}: a path model takes 0 to 16 hidden neurons");
    }
    let bar = progress(0, "fitting the path model");
    let model = PathModelFile::fit(ds, sha, hidden, PATH_RESTARTS, args.seed)
        .with_context(|| format!("{}", args.dataset.display()))?;
    bar.finish_and_clear();
    write_json(out, &model)?;
    let names = [
        "raw odometry",
        "kinematic fit",
        &format!("perceptron 2-{hidden}-3"),
    ];
    let recordings = ds
        .samples
        .iter()
        .map(|s| s.recording_id.as_str())
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    // These are the fit's own windows: a perceptron fitted to one recording read 65 mm here
    // against the kinematic fit's 117 mm, and held out the order flipped.
    say!(
        "path model: {} from {}; chained window end vs camera, training-set figures (RMS over the windows fitted, not held out; `odocal evaluate` judges other recordings):",
        count(model.n_windows, "window"),
        count(recordings, "recording")
    );
    for (name, f) in names.iter().zip(&model.window_fit) {
        say!(
            "  {name:<18} position {:7.1} mm   heading {:6.3} deg",
            1e3 * f.position_rms_m,
            f.heading_rms_rad.to_degrees()
        );
    }
    if let Some(w) = model.overfit_warning() {
        tell!("warning: {w}");
    }
    if recordings < MIN_PATH_RECORDINGS {
        tell!(
            "warning: the path model was fitted to {} ({} windows): a recording's windows overlap and share its floor, slip and tour, so the training-set figures above say little of another recording (a perceptron 2-2-3 fitted to one read 65 mm against the kinematic fit's 117 mm, and held out the order flipped); record at least {MIN_PATH_RECORDINGS} and judge the model with `odocal evaluate` on held-out recordings",
            count(recordings, "recording"),
            model.n_windows
        );
    }
    let g = &model.kinematic_fit;
    if let Some(w) = odocal_trainer::baseline::unlike_nominal_warning(g, &ds.robot, true) {
        tell!("warning: {w}");
    }
    say!(
        "kinematic fit: left wheel {:.3} mm, right wheel {:.3} mm, wheel base {:.2} mm (nominal {:.3} mm, {:.2} mm)",
        1e3 * g.left_wheel_diameter_m,
        1e3 * g.right_wheel_diameter_m,
        1e3 * g.wheel_base_m,
        1e3 * ds.robot.wheel_diameter_m,
        1e3 * ds.robot.wheel_base_m
    );
    commit()?;
    say!("wrote {}", out.display());
    Ok(())
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
    let (lo, hi) = (*HIDDEN_RANGE.start(), *HIDDEN_RANGE.end());
    if a < lo || b > hi {
        bail!("--sweep '{s}': hidden sizes must lie in {lo}..{hi}; give a range within it, e.g. 6..12");
    }
    Ok((a..=b).collect())
}

fn settings(args: &Args) -> anyhow::Result<TrainSettings> {
    let method: Method = args.method.as_deref().unwrap_or("lm").parse()?;
    let hidden = args.hidden.unwrap_or(8);
    if !HIDDEN_RANGE.contains(&hidden) {
        bail!(
            "--hidden {hidden} is outside {}..{}, the hidden sizes of a straight-run model",
            HIDDEN_RANGE.start(),
            HIDDEN_RANGE.end()
        );
    }
    let mut s = TrainSettings::new(hidden, method);
    if let Some(v) = args.weight_decay {
        if !(0.0..=odocal_trainer::MAX_WEIGHT_DECAY).contains(&v) {
            bail!(
                "--weight-decay {v}: give a penalty from 0 to {} (normalised units; a heavier one holds every weight at zero, a model that predicts the training's mean end whatever the log says)",
                odocal_trainer::MAX_WEIGHT_DECAY
            );
        }
        s.weight_decay = v;
    }
    if let Some(v) = args.val_fraction {
        s.val_fraction = v;
    }
    if let Some(v) = args.max_epochs {
        if v == 0 {
            bail!(
                "--max-epochs 0: training takes at least one epoch; give --max-epochs 1 or more (default {})",
                s.max_epochs
            );
        }
        s.max_epochs = v;
    }
    if let Some(v) = args.max_fail {
        if v == 0 {
            bail!(
                "--max-fail 0: early stopping waits at least one epoch without improvement; give --max-fail 1 or more (default {})",
                s.max_fail
            );
        }
        s.max_fail = v;
    }
    if let Some(v) = args.min_improvement {
        if !(0.0..1.0).contains(&v) {
            bail!(
                "--min-improvement {v}: a share of the validation error, from 0 up to (not including) 1; give e.g. --min-improvement {} (the default)",
                s.min_improvement
            );
        }
        s.min_improvement = v;
    }
    if let Some(v) = args.val_fraction {
        if !(0.0..0.5).contains(&v) {
            bail!(
                "--val-fraction {v}: the share of the runs held out for early stopping must be from 0 up to (not including) 0.5, so that most runs are fitted; give e.g. --val-fraction {} (the default)",
                TrainSettings::new(hidden, method).val_fraction
            );
        }
    }
    s.validate()?;
    Ok(s)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        check_output_file(out, "--out")?;
    }
    let folds = args.folds.unwrap_or(DEFAULT_FOLDS);
    if !args.no_cv && folds < 2 {
        bail!(
            "--folds {folds}: cross-validation needs at least 2 folds; give --folds 2 or more, or --no-cv in place of --folds"
        );
    }
    let bytes = std::fs::read(&args.dataset)
        .with_context(|| format!("cannot read {}", args.dataset.display()))?;
    let (ds, sha) = odocal_trainer::parse_dataset(&bytes, &args.dataset.display().to_string())?;
    if ds.is_windows() {
        return run_paths(&args, &ds, &sha);
    }
    refuse_unused_combinations(&args)?;
    let ts = settings(&args)?;
    // Cross-validation holds out every fold in turn and needs at least 2 samples in each. The
    // default on a small dataset only costs the one model its estimate (a warning); folds
    // asked for cannot be had.
    let n = ds.samples.len();
    if args.folds.is_some() && folds > n / 2 {
        bail!(
            "--folds {folds}: too few samples for {folds} folds: {} has {n}, enough for at most {} folds of 2; give --folds {} or fewer{}",
            args.dataset.display(),
            n / 2,
            n / 2,
            if args.sweep.is_some() { "" } else { ", or --no-cv in place of --folds" }
        );
    }
    let oracle = match &args.oracle {
        Some(p) => {
            let file = OracleFile::read(p)?;
            let name = p.display().to_string();
            // Another experiment's truth with the same run ids puts an oracle row in Table 2
            // that judges the corrector against the wrong robot.
            if let Some(w) = odocal_dataset::errors_against_truth(&ds, &file, &name)?
                .and_then(|e| e.mismatch_warning(&name))
            {
                tell!("warning: --oracle: {w}");
            }
            Some(oracle_ends(&ds, &file, &name)?)
        }
        None => None,
    };
    if let Some(range) = &args.sweep {
        return run_sweep(&args, range, &ds, &sha, ts, oracle.as_ref());
    }
    let Some(out) = &args.out else {
        bail!("give --out model.json to train a model, or --sweep A..B to cross-validate hidden sizes");
    };
    let folds = (!args.no_cv).then_some(folds);
    let bar = progress(folds.unwrap_or(0) as u64, "cross-val");
    let fitted = fit_model(&ds, &sha, &ts, args.seed, folds, oracle.as_ref(), &|| {
        bar.inc(1)
    })
    .with_context(|| format!("{}", args.dataset.display()))?;
    bar.finish_and_clear();
    for w in &fitted.warnings {
        tell!("warning: {w}");
    }
    if let Some(md) = &fitted.table2_markdown {
        say!("{md}");
    }
    write_json(out, &fitted.model)?;
    for line in fitted.summary(args.folds.unwrap_or(DEFAULT_FOLDS)) {
        say!("{line}");
    }
    commit()?;
    say!("wrote {}", out.display());
    Ok(())
}

/// `--sweep A..B`: Tables 1 and 2 over hidden sizes, printed and optionally written.
fn run_sweep(
    args: &Args,
    range: &str,
    ds: &Dataset,
    sha: &str,
    ts: TrainSettings,
    oracle: Option<&HashMap<String, [f64; 2]>>,
) -> anyhow::Result<()> {
    let sizes = parse_range(range)?;
    let restarts = args.restarts.unwrap_or(DEFAULT_RESTARTS);
    if restarts == 0 {
        bail!("--restarts 0: a sweep needs at least 1 restart per hidden size");
    }
    let folds = args.folds.unwrap_or(DEFAULT_FOLDS);
    let settings = SweepSettings {
        hidden_sizes: sizes.clone(),
        restarts,
        folds,
        train: ts,
        seed: args.seed,
    };
    if let Some(dir) = &args.report {
        check_output_dir(dir, "--report")?;
        for name in ["report.json", "report.md"] {
            check_output_file(&dir.join(name), "--report")?;
        }
    }
    let bar = progress((sizes.len() * restarts * folds) as u64, "training");
    let rep = sweep(ds, sha, &settings, oracle, &|| bar.inc(1))
        .with_context(|| format!("{}", args.dataset.display()))?;
    bar.finish_and_clear();
    for w in &rep.warnings {
        tell!("warning: {w}");
    }
    let md = report::markdown(&rep);
    say!("{md}");
    if let Some(dir) = &args.report {
        write_json(&dir.join("report.json"), &rep)?;
        write_atomic(&dir.join("report.md"), md.as_bytes())?;
        commit()?;
        tell!(
            "wrote {} and {}",
            dir.join("report.json").display(),
            dir.join("report.md").display()
        );
    }
    Ok(())
}
