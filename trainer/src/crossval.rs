//! Cross-validated experiments: k-fold over restarts for a sweep of hidden sizes,
//! with the baselines evaluated on the same folds.
//!
//! Table 1 scores every hidden size on the outer folds. Table 2 must not pick the size on
//! those same folds (that would favour the size that happened to suit them), so its
//! perceptron row is a nested cross-validation: on each outer fold's training part an inner
//! CV picks k, and the outer fold is predicted by that k's Table 1 trainings (no extra
//! outer training). Kernel ridge regression picks its bandwidth and regularisation the same
//! way. The inner folds are the other outer folds, so inner fold g of outer fold f trains on
//! neither f nor g: one such training serves both (f, g) and (g, f), which halves the inner
//! trainings.

use std::collections::{BTreeMap, HashMap};

use odocal_dataset::{Dataset, Sample};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::baseline::{raw_predict, KinematicCalibration, LinearRegression};
use crate::error::TrainError;
use crate::kernel_ridge::{grid_sse, KernelRidge, KernelRidgeParams};
use crate::metrics::{MeanSd, Metrics};
use crate::net::Perceptron;
use crate::train::{drives_backwards, train_runs, TrainSettings, HIDDEN_RANGE};

/// The `format` tag of sweep reports.
pub const REPORT_FORMAT: &str = "odocal.train-report/1";

/// Settings of a cross-validated sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepSettings {
    /// Hidden sizes to try.
    pub hidden_sizes: Vec<usize>,
    /// Random restarts (weight initialisations and validation splits) per size.
    pub restarts: usize,
    /// Number of folds.
    pub folds: usize,
    /// Training settings (the hidden size is replaced per sweep entry).
    pub train: TrainSettings,
    /// Master seed: folds and every training derive from it.
    pub seed: u64,
}

/// One row of Table 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Table1Row {
    /// Hidden size k.
    pub hidden: usize,
    /// Trainable parameters 21k+2.
    pub n_params: usize,
    /// Training residuals per fold (2 x samples the weights were fitted on).
    pub n_residuals: usize,
    /// Epoch of the kept weights, over restarts x folds.
    pub epochs: MeanSd,
    /// Training MSE per coordinate (samples fitted, without the early-stopping split), m^2, over restarts x folds.
    pub train_mse_m2: MeanSd,
    /// Cross-validated (held-out fold) MSE per coordinate, m^2, over restarts.
    pub val_mse_m2: MeanSd,
    /// Cross-validated relative end-point error, over restarts.
    pub val_rel_error: MeanSd,
}

/// Metrics of one method on one speed group.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedRow {
    /// Commanded speed, m/s.
    pub speed_mps: f64,
    /// Samples at this speed.
    pub n: usize,
    /// Cross-validated MSE per coordinate, m^2 (mean over restarts).
    pub mse_m2: f64,
    /// Cross-validated relative end-point error (mean over restarts).
    pub rel_error: f64,
}

/// One row of Table 2: one method, cross-validated on the shared folds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodRow {
    /// Method name.
    pub method: String,
    /// MSE per coordinate, m^2 (mean ± sd over restarts; sd 0 for deterministic methods).
    pub mse_m2: MeanSd,
    /// Relative end-point error (fraction), mean ± sd over restarts.
    pub rel_error: MeanSd,
    /// RMS end-point error, m (mean over restarts).
    pub rms_end_error_m: f64,
    /// Dataset size (samples).
    pub n_samples: usize,
    /// Mean real path length, m.
    pub mean_distance_m: f64,
    /// The same metrics per commanded speed (empty when runs have none:
    /// [`SweepReport::per_speed_left_out`]).
    pub per_speed: Vec<SpeedRow>,
}

/// Restarts per hidden size in the inner cross-validation that picks k for Table 2.
///
/// One, not the sweep's ten: the outer fold is then predicted by all the outer restarts of
/// the chosen size (Table 1's trainings), so inner restarts only serve the ranking, and more
/// of them did not rank better. On the 131-run experiment (seed 1, k = 6..12, 10 restarts)
/// 1, 2, 3, 5 and 10 inner restarts gave the perceptron row 4.53, 4.51, 4.47, 4.50 and
/// 4.47 % relative end-point error (restart-to-restart sd 0.12-0.15 points): the sizes are
/// within noise of each other there. Each inner restart costs 7 sizes x 10 fold pairs
/// trainings on 3/5 of the samples, about 15 % of the sweep's CPU time.
pub const INNER_RESTARTS: usize = 1;

/// What the nested cross-validation chose on one outer fold's training part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NestedChoice {
    /// Outer fold (0-based).
    pub fold: usize,
    /// Hidden size the perceptron row used on this fold.
    pub hidden: usize,
    /// Inner cross-validated MSE per coordinate of that size, m^2 (mean over the inner
    /// restarts); None when only one size was swept (nothing to choose).
    pub hidden_inner_mse_m2: Option<f64>,
    /// Kernel ridge regression's hyperparameters on this fold.
    pub kernel_ridge: KernelRidgeParams,
    /// Inner cross-validated MSE per coordinate of kernel ridge with them, m^2.
    pub kernel_ridge_inner_mse_m2: f64,
}

/// Result of a sweep: Table 1, Table 2, the calibration, and a plain verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Always [`REPORT_FORMAT`].
    pub format: String,
    /// SHA-256 of the dataset file.
    pub dataset_sha256: String,
    /// Samples in the dataset.
    pub n_samples: usize,
    /// The settings of the sweep.
    pub settings: SweepSettings,
    /// Table 1: one row per hidden size.
    pub table1: Vec<Table1Row>,
    /// Hidden size with the lowest cross-validated MSE in Table 1 (chosen on the outer folds
    /// themselves, so Table 2 does not use it: see [`SweepReport::nested`]).
    pub best_hidden: usize,
    /// Table 2: raw odometry, baselines, kernel ridge regression, the perceptron (k by nested
    /// cross-validation when several sizes are swept) and, if given, the oracle.
    pub table2: Vec<MethodRow>,
    /// Restarts per hidden size in the inner cross-validation ([`INNER_RESTARTS`] at most;
    /// 0 when one size is swept).
    #[serde(default)]
    pub inner_restarts: usize,
    /// The nested cross-validation's choices, one per outer fold (empty with fewer than 3
    /// folds: the inner CV needs two folds besides the outer test fold).
    #[serde(default)]
    pub nested: Vec<NestedChoice>,
    /// Why Table 2 has no rows per commanded speed ([`per_speed_left_out`]); None when it has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub per_speed_left_out: Option<String>,
    /// The kinematic calibration fitted on all samples (for a ROS diff_drive_controller).
    pub kinematic_calibration: KinematicCalibration,
    /// Warnings (e.g. parameter count near the number of residuals).
    pub warnings: Vec<String>,
    /// One-paragraph verdict: which method wins, by how much.
    pub verdict: String,
}

impl SweepReport {
    /// Reads the report.json that `odocal train --sweep --report DIR` writes.
    pub fn read(path: &std::path::Path) -> Result<Self, TrainError> {
        Ok(odocal_core::read_tagged_json(
            path,
            REPORT_FORMAT,
            "pass the report.json written by `odocal train --sweep --report DIR`",
        )?)
    }
}

/// Mixes a seed with task coordinates (SplitMix64 finaliser).
pub fn derive_seed(seed: u64, parts: &[u64]) -> u64 {
    let mut z = seed;
    for p in parts {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15).wrapping_add(*p);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
    }
    z
}

/// Speed group key (cm/s) of a sample.
fn speed_key(s: &Sample) -> i64 {
    (s.speed_mps * 100.0).round() as i64
}

/// Assigns each sample to a fold, stratified by commanded speed, deterministically for `seed`.
pub fn assign_folds(samples: &[Sample], folds: usize, seed: u64) -> Result<Vec<usize>, TrainError> {
    let n = samples.len();
    if folds < 2 {
        return Err(TrainError::Settings(format!(
            "folds = {folds}; need at least 2"
        )));
    }
    if n < 2 * folds || n - n.div_ceil(folds) < 8 {
        return Err(TrainError::TooFewSamples(format!(
            "{n} samples for {folds} folds; need at least 2 per fold and 8 to train on per fold"
        )));
    }
    let mut groups: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        groups.entry(speed_key(s)).or_default().push(i);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, &[0xF01D]));
    let mut fold = vec![0; n];
    let mut next = 0;
    for idx in groups.values_mut() {
        idx.shuffle(&mut rng);
        for &i in idx.iter() {
            fold[i] = next % folds;
            next += 1;
        }
    }
    Ok(fold)
}

/// Warning text when 21k+2 parameters approach the number of training residuals.
pub fn capacity_warning(hidden: usize, n_fit: usize) -> Option<String> {
    capacity_warning_sizes(&[hidden], n_fit)
}

/// [`capacity_warning`] for several hidden sizes trained on `n_fit` samples, as one line for
/// those it concerns (a sweep's larger sizes all do, and seven copies bury the report).
pub fn capacity_warning_sizes(hidden: &[usize], n_fit: usize) -> Option<String> {
    let r = 2 * n_fit;
    let params = |k: usize| Perceptron::n_params_for(odocal_dataset::N_INPUTS, k, 2);
    let over: Vec<usize> = hidden
        .iter()
        .copied()
        .filter(|&k| params(k) * 2 > r)
        .collect();
    let (&first, &last) = (over.first()?, over.last()?);
    let (sizes, count) = if first == last {
        (format!("k = {first}"), format!("{}", params(first)))
    } else {
        (
            format!(
                "k = {}",
                over.iter()
                    .map(|k| k.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            format!("{}-{}", params(first), params(last)),
        )
    };
    Some(format!(
        "{sizes}: {count} parameters (21k+2) against {r} training residuals (2 x {n_fit} samples): \
         the net can nearly interpolate the data; rely on early stopping / weight decay and the held-out figures"
    ))
}

/// One training of a sweep.
#[derive(Debug, Clone, Copy)]
enum Task {
    /// Table 1: size k, restart r, trained without outer fold f, predicts f.
    Outer { k: usize, r: usize, f: usize },
    /// Nested choice of k: size k, inner restart r, trained without folds a < b, predicts both.
    Inner {
        k: usize,
        r: usize,
        a: usize,
        b: usize,
    },
}

struct TaskOut {
    task: Task,
    hidden: usize,
    restart: usize,
    best_epoch: usize,
    n_fit: usize,
    train_mse_m2: f64,
    pred: Vec<(usize, [f64; 2])>,
}

/// Why errors cannot be given per commanded speed: runs whose manifest row has no
/// `speed_mps`, whose speed is then the odometry's cruise speed, which noise spreads over
/// nearly as many values as runs (0.17, 0.18, 0.20 m/s for one command of 0.2). None when every
/// run has its command.
pub fn per_speed_left_out(samples: &[Sample]) -> Option<String> {
    let n = samples.iter().filter(|s| !s.speed_commanded).count();
    (n > 0).then(|| {
        format!(
            "{n} of the {} runs have no speed_mps in the manifest, and their odometry's average speeds are no commanded speeds; give every run's speed_mps in the manifest for this table",
            samples.len()
        )
    })
}

fn method_row(name: &str, samples: &[Sample], preds: &[Vec<[f64; 2]>]) -> MethodRow {
    let all: Vec<&Sample> = samples.iter().collect();
    let ms: Vec<Metrics> = preds.iter().map(|p| Metrics::of(&all, p)).collect();
    let mut groups: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    if per_speed_left_out(samples).is_none() {
        for (i, s) in samples.iter().enumerate() {
            groups.entry(speed_key(s)).or_default().push(i);
        }
    }
    let per_speed = groups
        .iter()
        .map(|(key, idx)| {
            let sub: Vec<&Sample> = idx.iter().map(|&i| &samples[i]).collect();
            let gm: Vec<Metrics> = preds
                .iter()
                .map(|p| {
                    let sp: Vec<[f64; 2]> = idx.iter().map(|&i| p[i]).collect();
                    Metrics::of(&sub, &sp)
                })
                .collect();
            SpeedRow {
                speed_mps: *key as f64 / 100.0,
                n: idx.len(),
                mse_m2: MeanSd::of(&gm.iter().map(|m| m.mse_m2).collect::<Vec<_>>()).mean,
                rel_error: MeanSd::of(&gm.iter().map(|m| m.rel_error).collect::<Vec<_>>()).mean,
            }
        })
        .collect();
    MethodRow {
        method: name.to_string(),
        mse_m2: MeanSd::of(&ms.iter().map(|m| m.mse_m2).collect::<Vec<_>>()),
        rel_error: MeanSd::of(&ms.iter().map(|m| m.rel_error).collect::<Vec<_>>()),
        rms_end_error_m: MeanSd::of(&ms.iter().map(|m| m.rms_end_error_m).collect::<Vec<_>>()).mean,
        n_samples: samples.len(),
        mean_distance_m: samples.iter().map(|s| s.path_length_m).sum::<f64>()
            / samples.len().max(1) as f64,
        per_speed,
    }
}

/// Name of the perceptron row of Table 2 for hidden size `k` (a sweep of one size).
pub fn net_method_name(k: usize) -> String {
    format!("perceptron 18-{k}-2")
}
/// Name of the perceptron row of Table 2 when k is chosen per outer fold by nested CV.
pub const NESTED_NET: &str = "perceptron 18-k-2, k by nested CV";
/// Name of the kernel ridge regression row.
pub const KERNEL_RIDGE: &str = "kernel ridge regression (RBF)";
/// Name of the raw odometry row.
pub const RAW: &str = "raw odometry";
/// Name of the row that predicts every run's end as the mean end of the training runs driven
/// the same way (forwards or backwards, the one thing it reads of the log): a corrector that does no better has learned the odometry's mean bias, nothing from the log.
pub const MEAN_END: &str = "mean end point (ignores the log)";
/// Name of the kinematic calibration row.
pub const KINEMATIC: &str = "kinematic calibration";
/// Name of the linear regression row.
pub const LINEAR: &str = "linear regression";
/// Name of the oracle row.
pub const ORACLE: &str = "oracle (true systematic parameters)";

/// Runs the cross-validated sweep and the baselines on the same folds, and the nested
/// cross-validation of Table 2 (kernel ridge regression always, the perceptron's k when
/// several sizes are swept; needs at least 3 folds). `oracle` maps run ids to the end point
/// corrected with the simulator's true systematic parameters. `tick` is called once per
/// finished Table 1 training, sizes x restarts x folds times in all (for progress bars; the
/// fewer, smaller inner trainings run interleaved with them and are not counted).
pub fn sweep(
    ds: &Dataset,
    dataset_sha256: &str,
    settings: &SweepSettings,
    oracle: Option<&HashMap<String, [f64; 2]>>,
    tick: &(dyn Fn() + Sync),
) -> Result<SweepReport, TrainError> {
    crate::data::check_dataset(ds)?;
    if settings.hidden_sizes.is_empty() {
        return Err(TrainError::Settings("no hidden sizes to sweep".into()));
    }
    for &k in &settings.hidden_sizes {
        if !HIDDEN_RANGE.contains(&k) {
            return Err(TrainError::Settings(format!(
                "hidden size k = {k} is outside {}..={}",
                HIDDEN_RANGE.start(),
                HIDDEN_RANGE.end()
            )));
        }
    }
    if settings.restarts == 0 {
        return Err(TrainError::Settings("restarts must be at least 1".into()));
    }
    let mut probe = settings.train.clone();
    probe.hidden = settings.hidden_sizes[0];
    probe.validate()?;
    let samples = &ds.samples;
    let n = samples.len();
    let fold = assign_folds(samples, settings.folds, settings.seed)?;
    // Before any training: a calibration no real robot has condemns the dataset.
    let all: Vec<&Sample> = samples.iter().collect();
    let kinematic_calibration = KinematicCalibration::fit(&all, &ds.robot)?;
    kinematic_calibration.check_physical()?;
    let fold_sets: Vec<(Vec<usize>, Vec<usize>)> = (0..settings.folds)
        .map(|f| {
            let test: Vec<usize> = (0..n).filter(|&i| fold[i] == f).collect();
            let fit: Vec<usize> = (0..n).filter(|&i| fold[i] != f).collect();
            (fit, test)
        })
        .collect();
    let oracle_preds = match oracle {
        Some(map) => {
            let mut v = Vec::with_capacity(n);
            for s in samples {
                match map.get(&s.run_id) {
                    Some(p) if p.iter().all(|x| x.is_finite()) => v.push(*p),
                    _ => {
                        return Err(TrainError::Dataset(format!(
                            "oracle has no finite end point for run '{}'",
                            s.run_id
                        )))
                    }
                }
            }
            Some(v)
        }
        None => None,
    };

    // Baselines on the same folds.
    let mut raw = vec![[0.0; 2]; n];
    let mut kin = vec![[0.0; 2]; n];
    let mut lin = vec![[0.0; 2]; n];
    let mut mean = vec![[0.0; 2]; n];
    for (fit, test) in &fold_sets {
        let fit_s: Vec<&Sample> = fit.iter().map(|&i| &samples[i]).collect();
        let kc = KinematicCalibration::fit(&fit_s, &ds.robot)?;
        let lr = LinearRegression::fit(&fit_s)?;
        let mean_end = mean_target_by_direction(&fit_s);
        for &i in test {
            raw[i] = raw_predict(&samples[i]);
            mean[i] = mean_end[usize::from(drives_backwards(&samples[i].inputs))];
            kin[i] = kc.predict(&samples[i]);
            lin[i] = lr.predict(&samples[i]);
        }
    }

    // Nested cross-validation needs two folds besides the outer test fold.
    let nested_ok = settings.folds >= 3;
    let choose_k = settings.hidden_sizes.len() > 1;
    if choose_k && !nested_ok {
        return Err(TrainError::Settings(format!(
            "folds = {}: choosing the hidden size by nested cross-validation needs at least 3 folds \
             (or sweep one size)",
            settings.folds
        )));
    }
    let inner: Vec<Vec<InnerSplit>> = (0..settings.folds)
        .map(|f| inner_splits(&fold, settings.folds, f))
        .collect();
    let inner_restarts = if choose_k {
        settings.restarts.min(INNER_RESTARTS)
    } else {
        0
    };

    // The perceptron: Table 1's sizes x restarts x folds, and for the nested choice of k
    // sizes x inner restarts x pairs of folds, in parallel, each task seeded on its own.
    // Inner tasks are spread evenly among the outer ones so that progress (ticked per outer
    // training) runs at an even pace.
    let outer_tasks: Vec<Task> = settings
        .hidden_sizes
        .iter()
        .flat_map(|&k| {
            (0..settings.restarts)
                .flat_map(move |r| (0..settings.folds).map(move |f| Task::Outer { k, r, f }))
        })
        .collect();
    let inner_tasks: Vec<Task> = settings
        .hidden_sizes
        .iter()
        .flat_map(|&k| {
            (0..inner_restarts).flat_map(move |r| {
                (0..settings.folds).flat_map(move |a| {
                    (a + 1..settings.folds).map(move |b| Task::Inner { k, r, a, b })
                })
            })
        })
        .collect();
    let mut tasks = Vec::with_capacity(outer_tasks.len() + inner_tasks.len());
    let mut inner_iter = inner_tasks.iter();
    for (j, t) in outer_tasks.iter().enumerate() {
        tasks.push(*t);
        // Inner tasks queued so far: tasks.len() - (j + 1); keep them in proportion.
        while (tasks.len() - j - 1) * outer_tasks.len() < (j + 1) * inner_tasks.len() {
            match inner_iter.next() {
                Some(i) => tasks.push(*i),
                None => break,
            }
        }
    }
    tasks.extend(inner_iter);

    let inputs: Vec<Vec<f64>> = samples.iter().map(|s| s.inputs.clone()).collect();
    let targets: Vec<[f64; 2]> = samples.iter().map(|s| s.target_m).collect();
    let outs: Vec<TaskOut> = tasks
        .par_iter()
        .map(|task| {
            // Training rows, the rows to predict, and the training's seed.
            let (k, r, fit, test, seed) = match *task {
                Task::Outer { k, r, f } => {
                    let (fit, test) = &fold_sets[f];
                    let seed = derive_seed(settings.seed, &[k as u64, r as u64, f as u64]);
                    (k, r, fit.as_slice(), test.clone(), seed)
                }
                Task::Inner { k, r, a, b } => {
                    // Inner fold b of outer fold a: trained on neither a nor b. It predicts
                    // fold b for outer fold a's choice and fold a for outer fold b's.
                    let split = inner[a].iter().find(|s| s.fold == b).ok_or_else(|| {
                        TrainError::Numerical(format!("no inner fold {b} of outer fold {a}"))
                    })?;
                    let mut test = split.test.clone();
                    test.extend((0..n).filter(|&i| fold[i] == a));
                    let seed = derive_seed(
                        settings.seed,
                        &[0x1EEE, k as u64, r as u64, a as u64, b as u64],
                    );
                    (k, r, split.train.as_slice(), test, seed)
                }
            };
            let mut ts = settings.train.clone();
            ts.hidden = k;
            let fin: Vec<Vec<f64>> = fit.iter().map(|&i| inputs[i].clone()).collect();
            let ftg: Vec<[f64; 2]> = fit.iter().map(|&i| targets[i]).collect();
            let net = train_runs(&fin, &ftg, &ts, seed)?;
            let pred = test.iter().map(|&i| (i, net.predict(&inputs[i]))).collect();
            let train_mse_m2 = match task {
                Task::Outer { .. } => {
                    let fit_s: Vec<&Sample> =
                        net.fit_indices.iter().map(|&j| &samples[fit[j]]).collect();
                    let fit_p: Vec<[f64; 2]> = net
                        .fit_indices
                        .iter()
                        .map(|&j| net.predict(&fin[j]))
                        .collect();
                    tick();
                    Metrics::of(&fit_s, &fit_p).mse_m2
                }
                Task::Inner { .. } => f64::NAN,
            };
            Ok(TaskOut {
                task: *task,
                hidden: k,
                restart: r,
                best_epoch: net.best_epoch,
                n_fit: net.n_fit,
                train_mse_m2,
                pred,
            })
        })
        .collect::<Result<_, TrainError>>()?;
    let (outs, inner_outs): (Vec<TaskOut>, Vec<TaskOut>) = outs
        .into_iter()
        .partition(|o| matches!(o.task, Task::Outer { .. }));

    let mut table1 = Vec::new();
    let mut net_preds: HashMap<usize, Vec<Vec<[f64; 2]>>> = HashMap::new();
    let mut warnings = Vec::new();
    // Hidden sizes by the number of samples they were fitted on, for one capacity warning each.
    let mut fitted: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for &k in &settings.hidden_sizes {
        let mine: Vec<&TaskOut> = outs.iter().filter(|o| o.hidden == k).collect();
        let mut per_restart = vec![vec![[f64::NAN; 2]; n]; settings.restarts];
        for o in &mine {
            for &(i, p) in &o.pred {
                per_restart[o.restart][i] = p;
            }
        }
        let ms: Vec<Metrics> = per_restart.iter().map(|p| Metrics::of(&all, p)).collect();
        let n_fit = mine.iter().map(|o| o.n_fit).min().unwrap_or(0);
        fitted.entry(n_fit).or_default().push(k);
        table1.push(Table1Row {
            hidden: k,
            n_params: Perceptron::n_params_for(odocal_dataset::N_INPUTS, k, 2),
            n_residuals: 2 * n_fit,
            epochs: MeanSd::of(&mine.iter().map(|o| o.best_epoch as f64).collect::<Vec<_>>()),
            train_mse_m2: MeanSd::of(&mine.iter().map(|o| o.train_mse_m2).collect::<Vec<_>>()),
            val_mse_m2: MeanSd::of(&ms.iter().map(|m| m.mse_m2).collect::<Vec<_>>()),
            val_rel_error: MeanSd::of(&ms.iter().map(|m| m.rel_error).collect::<Vec<_>>()),
        });
        net_preds.insert(k, per_restart);
    }
    warnings.extend(
        fitted
            .iter()
            .filter_map(|(&n_fit, ks)| capacity_warning_sizes(ks, n_fit)),
    );
    // The size Table 1 marks: lowest MSE on the outer folds themselves (not used by Table 2).
    let best = table1
        .iter()
        .min_by(|a, b| a.val_mse_m2.mean.total_cmp(&b.val_mse_m2.mean))
        .map(|r| r.hidden)
        .unwrap_or(settings.hidden_sizes[0]);

    // Nested choice of k: per outer fold, the size with the lowest inner cross-validated MSE
    // (mean over inner restarts) on the outer training part; ties go to the earlier size.
    let mut hidden_choice: Vec<(usize, Option<f64>)> =
        vec![(settings.hidden_sizes[0], None); settings.folds];
    if choose_k {
        for (f, choice) in hidden_choice.iter_mut().enumerate() {
            let part: Vec<usize> = (0..n).filter(|&i| fold[i] != f).collect();
            let part_s: Vec<&Sample> = part.iter().map(|&i| &samples[i]).collect();
            let mut best_k: Option<(usize, f64)> = None;
            for &k in &settings.hidden_sizes {
                let mut mses = Vec::with_capacity(inner_restarts);
                for r in 0..inner_restarts {
                    let mut pred = vec![[f64::NAN; 2]; n];
                    for o in &inner_outs {
                        let Task::Inner { a, b, .. } = o.task else {
                            continue;
                        };
                        if o.hidden != k || o.restart != r || (a != f && b != f) {
                            continue;
                        }
                        // Only the other fold of the pair is outer fold f's inner test fold.
                        for &(i, p) in &o.pred {
                            if fold[i] != f {
                                pred[i] = p;
                            }
                        }
                    }
                    let p: Vec<[f64; 2]> = part.iter().map(|&i| pred[i]).collect();
                    mses.push(Metrics::of(&part_s, &p).mse_m2);
                }
                let mse = MeanSd::of(&mses).mean;
                if !mse.is_finite() {
                    return Err(TrainError::Numerical(format!(
                        "inner cross-validation of k = {k} on outer fold {f}: MSE not finite"
                    )));
                }
                if best_k.is_none_or(|(_, m)| mse < m) {
                    best_k = Some((k, mse));
                }
            }
            if let Some((k, mse)) = best_k {
                *choice = (k, Some(mse));
            }
        }
    }
    // Table 2's perceptron: restart r predicts outer fold f with Table 1's training (k_f, r, f).
    let nested_preds: Vec<Vec<[f64; 2]>> = (0..settings.restarts)
        .map(|r| {
            (0..n)
                .map(|i| net_preds[&hidden_choice[fold[i]].0][r][i])
                .collect()
        })
        .collect();

    // Kernel ridge regression, its hyperparameters chosen on each outer training part.
    let mut nested = Vec::new();
    let mut krr_row = None;
    if nested_ok {
        let grid = KernelRidgeParams::grid();
        let per_fold: Vec<KernelRidgeFold> = (0..settings.folds)
            .into_par_iter()
            .map(|f| kernel_ridge_fold(samples, &inner[f], &fold_sets[f], &grid, f))
            .collect::<Result<_, TrainError>>()?;
        let mut krr = vec![[f64::NAN; 2]; n];
        for (f, kf) in per_fold.into_iter().enumerate() {
            for (i, p) in kf.pred {
                krr[i] = p;
            }
            nested.push(NestedChoice {
                fold: f,
                hidden: hidden_choice[f].0,
                hidden_inner_mse_m2: hidden_choice[f].1,
                kernel_ridge: kf.params,
                kernel_ridge_inner_mse_m2: kf.inner_mse_m2,
            });
        }
        krr_row = Some(method_row(KERNEL_RIDGE, samples, &[krr]));
    } else {
        warnings.push(format!(
            "folds = {}: kernel ridge regression left out of Table 2 (choosing its bandwidth and \
             regularisation by nested cross-validation needs at least 3 folds)",
            settings.folds
        ));
    }

    let net_name = if choose_k {
        NESTED_NET.to_string()
    } else {
        net_method_name(settings.hidden_sizes[0])
    };
    let mut table2 = vec![
        method_row(RAW, samples, &[raw]),
        method_row(MEAN_END, samples, &[mean]),
        method_row(KINEMATIC, samples, &[kin]),
        method_row(LINEAR, samples, &[lin]),
    ];
    table2.extend(krr_row);
    table2.push(method_row(&net_name, samples, &nested_preds));
    if let Some(o) = oracle_preds {
        table2.push(method_row(ORACLE, samples, &[o]));
    }
    warnings.extend(no_better_than_the_mean(&table2, &net_name));
    let verdict = verdict(&table2, &net_name);
    Ok(SweepReport {
        format: REPORT_FORMAT.to_string(),
        dataset_sha256: dataset_sha256.to_string(),
        n_samples: n,
        settings: settings.clone(),
        table1,
        best_hidden: best,
        table2,
        inner_restarts,
        nested,
        per_speed_left_out: per_speed_left_out(samples),
        kinematic_calibration,
        warnings,
        verdict,
    })
}

/// Kernel ridge regression on one outer fold: the choice of its inner CV and the predictions.
struct KernelRidgeFold {
    params: KernelRidgeParams,
    inner_mse_m2: f64,
    pred: Vec<(usize, [f64; 2])>,
}

/// Chooses kernel ridge's hyperparameters from `grid` by the inner splits of outer fold
/// `outer`, fits them on the outer training part and predicts the outer test fold.
fn kernel_ridge_fold(
    samples: &[Sample],
    inner: &[InnerSplit],
    (fit, test): &(Vec<usize>, Vec<usize>),
    grid: &[KernelRidgeParams],
    outer: usize,
) -> Result<KernelRidgeFold, TrainError> {
    let mut sse = vec![0.0; grid.len()];
    let mut n_inner = 0;
    for split in inner {
        let tr: Vec<&Sample> = split.train.iter().map(|&i| &samples[i]).collect();
        let te: Vec<&Sample> = split.test.iter().map(|&i| &samples[i]).collect();
        for (acc, v) in sse.iter_mut().zip(grid_sse(&tr, &te, grid)?) {
            *acc += v;
        }
        n_inner += te.len();
    }
    // Lowest inner error; ties go to the earlier (smoother) grid entry.
    let mut pick = 0;
    for (j, v) in sse.iter().enumerate() {
        if *v < sse[pick] {
            pick = j;
        }
    }
    if !sse.get(pick).is_some_and(|v| v.is_finite()) {
        return Err(TrainError::Numerical(format!(
            "kernel ridge inner cross-validation on outer fold {outer}: error not finite"
        )));
    }
    let fit_s: Vec<&Sample> = fit.iter().map(|&i| &samples[i]).collect();
    let test_s: Vec<&Sample> = test.iter().map(|&i| &samples[i]).collect();
    let model = KernelRidge::fit(&fit_s, grid[pick])?;
    Ok(KernelRidgeFold {
        params: grid[pick],
        inner_mse_m2: sse[pick] / (2 * n_inner.max(1)) as f64,
        pred: test.iter().copied().zip(model.predict(&test_s)).collect(),
    })
}

/// One fold of the inner cross-validation of an outer fold.
#[derive(Debug, Clone, PartialEq)]
pub struct InnerSplit {
    /// The outer fold whose samples this inner fold tests on.
    pub fold: usize,
    /// Samples trained on: in neither the outer test fold nor this inner fold.
    pub train: Vec<usize>,
    /// Samples predicted: those of this inner fold.
    pub test: Vec<usize>,
}

/// The inner cross-validation of outer fold `outer` (`fold` from [`assign_folds`]): its
/// folds are the other outer folds, so it sees only the outer training part; no sample of
/// fold `outer` is trained on or tested.
pub fn inner_splits(fold: &[usize], folds: usize, outer: usize) -> Vec<InnerSplit> {
    (0..folds)
        .filter(|&g| g != outer)
        .map(|g| InnerSplit {
            fold: g,
            train: (0..fold.len())
                .filter(|&i| fold[i] != outer && fold[i] != g)
                .collect(),
            test: (0..fold.len()).filter(|&i| fold[i] == g).collect(),
        })
        .collect()
}

/// The mean end point of `samples`' targets, metres.
fn mean_target(samples: &[&Sample]) -> [f64; 2] {
    let n = samples.len().max(1) as f64;
    let sum = samples.iter().fold([0.0; 2], |a, s| {
        [a[0] + s.target_m[0], a[1] + s.target_m[1]]
    });
    [sum[0] / n, sum[1] / n]
}

/// The mean end point of `samples`' targets per direction of travel, [forwards, backwards],
/// metres. The mean of runs driven both ways lies near the start, where no run ends: beside
/// it any corrector would seem to read the log. A direction without runs takes all runs' mean.
fn mean_target_by_direction(samples: &[&Sample]) -> [[f64; 2]; 2] {
    let all = mean_target(samples);
    [false, true].map(|back| {
        let one_way: Vec<&Sample> = samples
            .iter()
            .copied()
            .filter(|s| drives_backwards(&s.inputs) == back)
            .collect();
        if one_way.is_empty() {
            all
        } else {
            mean_target(&one_way)
        }
    })
}

/// How much better than the mean end point a corrector must be to have learned something
/// from the log: 10 %, about twice the restart-to-restart spread of the reference
/// experiment's perceptron.
const MEAN_MARGIN: f64 = 0.9;

/// A warning when the corrector `name` is not clearly better than predicting every run's
/// end as the training runs' mean end: its figures then show the odometry's mean bias
/// removed, which says nothing of how it corrects a run unlike the training's.
pub fn no_better_than_the_mean(t: &[MethodRow], name: &str) -> Option<String> {
    let (mean, net) = (row(t, MEAN_END)?, row(t, name)?);
    (net.rel_error.mean > MEAN_MARGIN * mean.rel_error.mean).then(|| {
        format!(
            "the {name} ({:.2} % cross-validated) is not {:.0} % better than the training runs' mean end point ({:.2} %), which ignores the log: the runs end too alike (mean distance {:.3} m) for the odometry to tell them apart, so the figures show the mean bias removed, not the log corrected; record runs of several lengths and speeds for a corrector that uses the log",
            100.0 * net.rel_error.mean,
            100.0 * (1.0 - MEAN_MARGIN),
            100.0 * mean.rel_error.mean,
            mean.mean_distance_m
        )
    })
}

/// Row of Table 2 by method name.
pub fn row<'a>(table2: &'a [MethodRow], name: &str) -> Option<&'a MethodRow> {
    table2.iter().find(|r| r.method == name)
}

fn verdict(t: &[MethodRow], name: &str) -> String {
    let (Some(raw), Some(kin), Some(net)) = (row(t, RAW), row(t, KINEMATIC), row(t, name)) else {
        return String::new();
    };
    let pct = |r: &MethodRow| 100.0 * r.rel_error.mean;
    let krr = row(t, KERNEL_RIDGE);
    let mut s = format!(
        "Cross-validated relative end-point error: raw odometry {:.2} %, kinematic calibration {:.2} %, {}{} {:.2} % ({:.0} % of raw). ",
        pct(raw),
        pct(kin),
        krr.map(|r| format!("{KERNEL_RIDGE} {:.2} %, ", pct(r)))
            .unwrap_or_default(),
        name,
        pct(net),
        100.0 * net.rel_error.mean / raw.rel_error.mean
    );
    if let Some(m) = row(t, MEAN_END) {
        s += &format!(
            "The training runs' mean end point, which ignores the log, reaches {:.2} %{}. ",
            pct(m),
            if net.rel_error.mean > MEAN_MARGIN * m.rel_error.mean {
                ": the runs end too alike to show what the perceptron learns from the log"
            } else {
                ""
            }
        );
    }
    let margin = (net.rel_error.mean - kin.rel_error.mean).abs();
    let tie = margin <= net.rel_error.sd.max(0.02 * kin.rel_error.mean);
    if net.rel_error.mean < kin.rel_error.mean {
        s += &format!(
            "The perceptron wins over the kinematic calibration ({:.2} % vs {:.2} %).",
            pct(net),
            pct(kin)
        );
        if tie {
            s += &format!(
                " The margin ({:.2} points) is within the restart-to-restart spread (sd {:.2} points): in practice a tie, and the three-parameter calibration is the simpler tool.",
                100.0 * margin,
                100.0 * net.rel_error.sd
            );
        }
    } else {
        s += &format!(
            "The kinematic calibration wins over the perceptron ({:.2} % vs {:.2} %): three physical parameters do at least as well as the net.",
            pct(kin),
            pct(net)
        );
    }
    if let Some(k) = krr {
        let who = if k.rel_error.mean < net.rel_error.mean {
            "beats"
        } else {
            "does not beat"
        };
        s += &format!(
            " Kernel ridge regression, the strongest simple peer, {who} the perceptron ({:.2} % vs {:.2} %).",
            pct(k),
            pct(net)
        );
    }
    if let Some(o) = row(t, ORACLE) {
        s += &format!(
            " The oracle with the true systematic parameters reaches {:.2} %; the perceptron is at {:.2}x the oracle, the kinematic calibration at {:.2}x{}.",
            pct(o),
            net.rel_error.mean / o.rel_error.mean,
            kin.rel_error.mean / o.rel_error.mean,
            krr.map(|k| format!(
                ", kernel ridge regression at {:.2}x",
                k.rel_error.mean / o.rel_error.mean
            ))
            .unwrap_or_default()
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn method(name: &str, rel_error: f64) -> MethodRow {
        let m = MeanSd {
            mean: rel_error,
            sd: 0.0,
        };
        MethodRow {
            method: name.into(),
            mse_m2: m,
            rel_error: m,
            rms_end_error_m: 0.0,
            n_samples: 10,
            mean_distance_m: 1.5,
            per_speed: Vec::new(),
        }
    }

    #[test]
    fn errors_are_given_per_commanded_speed_only() {
        let sample = |v: f64, commanded: bool| Sample {
            run_id: "r".into(),
            speed_mps: v,
            speed_commanded: commanded,
            target_m: [1.0, 0.0],
            raw_end_m: [1.1, 0.0],
            path_length_m: 1.0,
            ..Sample::default()
        };
        let preds = vec![vec![[1.05, 0.0]; 5]];
        // Three commands, 0.2, 0.5 and 0.7 m/s: one column each.
        let commanded: Vec<Sample> = [0.2, 0.2, 0.5, 0.5, 0.7]
            .iter()
            .map(|&v| sample(v, true))
            .collect();
        assert_eq!(per_speed_left_out(&commanded), None);
        let row = method_row("raw odometry", &commanded, &preds);
        let cols: Vec<(f64, usize)> = row.per_speed.iter().map(|p| (p.speed_mps, p.n)).collect();
        assert_eq!(cols, [(0.2, 2), (0.5, 2), (0.7, 1)]);
        assert!(row
            .per_speed
            .iter()
            .all(|p| (p.rel_error - 0.05).abs() < 1e-12));
        // The odometry's average speeds of one command of 0.2 m/s are no three commands.
        let measured: Vec<Sample> = [0.17, 0.18, 0.20, 0.48, 0.66]
            .iter()
            .map(|&v| sample(v, false))
            .collect();
        assert!(method_row("raw odometry", &measured, &preds)
            .per_speed
            .is_empty());
        assert_eq!(
            per_speed_left_out(&measured).unwrap(),
            "5 of the 5 runs have no speed_mps in the manifest, and their odometry's average speeds are no commanded speeds; give every run's speed_mps in the manifest for this table"
        );
        // A dataset written before the flag was recorded keeps its table.
        let mut old = serde_json::to_value(sample(0.2, false)).unwrap();
        old.as_object_mut().unwrap().remove("speed_commanded");
        assert!(
            serde_json::from_value::<Sample>(old)
                .unwrap()
                .speed_commanded
        );
    }

    #[test]
    fn a_corrector_no_better_than_the_mean_end_is_warned() {
        let net = "perceptron 18-8-2";
        let rows = |net_error| vec![method(MEAN_END, 0.0434), method(net, net_error)];
        // 4.54 % against the mean's 4.34 % (the reference experiment's figures).
        let w = no_better_than_the_mean(&rows(0.0454), net).expect("warned");
        assert!(
            w.starts_with("the perceptron 18-8-2 (4.54 % cross-validated) is not 10 % better than the training runs' mean end point (4.34 %)"),
            "{w}"
        );
        // Within 10 % of it is no better either; clearly below it is.
        assert!(no_better_than_the_mean(&rows(0.040), net).is_some());
        assert!(no_better_than_the_mean(&rows(0.038), net).is_none());
        assert!(no_better_than_the_mean(&[method(net, 0.05)], net).is_none());
        assert!(verdict(
            &[
                method(RAW, 0.09),
                method(MEAN_END, 0.0434),
                method(KINEMATIC, 0.0458),
                method(net, 0.0454)
            ],
            net
        )
        .contains("The training runs' mean end point, which ignores the log, reaches 4.34 %: the runs end too alike"));
    }

    #[test]
    fn a_sweep_gets_one_capacity_warning() {
        // 88 samples fit: 176 residuals; k = 4 has 86 parameters (under half), k ≥ 5 more.
        let w = capacity_warning_sizes(&[4, 5, 6, 7], 88).expect("warned");
        assert!(
            w.starts_with("k = 5, 6, 7: 107-149 parameters (21k+2) against 176"),
            "{w}"
        );
        assert_eq!(capacity_warning_sizes(&[2, 3, 4], 88), None);
        let one = capacity_warning(8, 111).expect("warned");
        assert!(
            one.starts_with("k = 8: 170 parameters (21k+2) against 222"),
            "{one}"
        );
    }
}
