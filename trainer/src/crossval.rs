//! Cross-validated experiments: k-fold over restarts for a sweep of hidden sizes,
//! with the baselines evaluated on the same folds.

use std::collections::{BTreeMap, HashMap};

use odocal_dataset::{Dataset, Sample};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::baseline::{raw_predict, KinematicCalibration, LinearRegression};
use crate::error::TrainError;
use crate::metrics::{MeanSd, Metrics};
use crate::net::Perceptron;
use crate::train::{train, TrainSettings, HIDDEN_RANGE};

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
    /// The same metrics per commanded speed.
    pub per_speed: Vec<SpeedRow>,
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
    /// Hidden size with the lowest cross-validated MSE.
    pub best_hidden: usize,
    /// Table 2: raw odometry, baselines, the perceptron (best k) and, if given, the oracle.
    pub table2: Vec<MethodRow>,
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
    let p = Perceptron::n_params_for(odocal_dataset::N_INPUTS, hidden, 2);
    let r = 2 * n_fit;
    (p * 2 > r).then(|| {
        format!(
            "k = {hidden}: {p} parameters (21k+2) against {r} training residuals (2 x {n_fit} samples): \
             the net can nearly interpolate the data; rely on early stopping / weight decay and the held-out figures"
        )
    })
}

struct TaskOut {
    hidden: usize,
    restart: usize,
    best_epoch: usize,
    n_fit: usize,
    train_mse_m2: f64,
    pred: Vec<(usize, [f64; 2])>,
}

fn method_row(name: &str, samples: &[Sample], preds: &[Vec<[f64; 2]>]) -> MethodRow {
    let all: Vec<&Sample> = samples.iter().collect();
    let ms: Vec<Metrics> = preds.iter().map(|p| Metrics::of(&all, p)).collect();
    let mut groups: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        groups.entry(speed_key(s)).or_default().push(i);
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

/// Name of the perceptron row of Table 2 for hidden size `k`.
pub fn net_method_name(k: usize) -> String {
    format!("perceptron 18-{k}-2")
}
/// Name of the raw odometry row.
pub const RAW: &str = "raw odometry";
/// Name of the kinematic calibration row.
pub const KINEMATIC: &str = "kinematic calibration";
/// Name of the linear regression row.
pub const LINEAR: &str = "linear regression";
/// Name of the oracle row.
pub const ORACLE: &str = "oracle (true systematic parameters)";

/// Runs the cross-validated sweep and the baselines on the same folds. `oracle` maps run
/// ids to the end point corrected with the simulator's true systematic parameters.
/// `tick` is called once per finished training (for progress bars).
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
    for (fit, test) in &fold_sets {
        let fit_s: Vec<&Sample> = fit.iter().map(|&i| &samples[i]).collect();
        let kc = KinematicCalibration::fit(&fit_s, &ds.robot)?;
        let lr = LinearRegression::fit(&fit_s)?;
        for &i in test {
            raw[i] = raw_predict(&samples[i]);
            kin[i] = kc.predict(&samples[i]);
            lin[i] = lr.predict(&samples[i]);
        }
    }

    // The perceptron: sizes x restarts x folds, in parallel, each task seeded on its own.
    let tasks: Vec<(usize, usize, usize)> = settings
        .hidden_sizes
        .iter()
        .flat_map(|&k| {
            (0..settings.restarts).flat_map(move |r| (0..settings.folds).map(move |f| (k, r, f)))
        })
        .collect();
    let inputs: Vec<Vec<f64>> = samples.iter().map(|s| s.inputs.clone()).collect();
    let targets: Vec<[f64; 2]> = samples.iter().map(|s| s.target_m).collect();
    let outs: Vec<TaskOut> = tasks
        .par_iter()
        .map(|&(k, r, f)| {
            let (fit, test) = &fold_sets[f];
            let mut ts = settings.train.clone();
            ts.hidden = k;
            let fin: Vec<Vec<f64>> = fit.iter().map(|&i| inputs[i].clone()).collect();
            let ftg: Vec<[f64; 2]> = fit.iter().map(|&i| targets[i]).collect();
            let seed = derive_seed(settings.seed, &[k as u64, r as u64, f as u64]);
            let net = train(&fin, &ftg, &ts, seed)?;
            let fit_s: Vec<&Sample> = net.fit_indices.iter().map(|&j| &samples[fit[j]]).collect();
            let fit_p: Vec<[f64; 2]> = net
                .fit_indices
                .iter()
                .map(|&j| net.predict(&fin[j]))
                .collect();
            let pred = test.iter().map(|&i| (i, net.predict(&inputs[i]))).collect();
            tick();
            Ok(TaskOut {
                hidden: k,
                restart: r,
                best_epoch: net.best_epoch,
                n_fit: net.n_fit,
                train_mse_m2: Metrics::of(&fit_s, &fit_p).mse_m2,
                pred,
            })
        })
        .collect::<Result<_, TrainError>>()?;

    let all: Vec<&Sample> = samples.iter().collect();
    let mut table1 = Vec::new();
    let mut net_preds: HashMap<usize, Vec<Vec<[f64; 2]>>> = HashMap::new();
    let mut warnings = Vec::new();
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
        if let Some(w) = capacity_warning(k, n_fit) {
            warnings.push(w);
        }
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
    let best = table1
        .iter()
        .min_by(|a, b| a.val_mse_m2.mean.total_cmp(&b.val_mse_m2.mean))
        .map(|r| r.hidden)
        .unwrap_or(settings.hidden_sizes[0]);

    let mut table2 = vec![
        method_row(RAW, samples, &[raw]),
        method_row(KINEMATIC, samples, &[kin]),
        method_row(LINEAR, samples, &[lin]),
        method_row(&net_method_name(best), samples, &net_preds[&best]),
    ];
    if let Some(o) = oracle_preds {
        table2.push(method_row(ORACLE, samples, &[o]));
    }
    let kinematic_calibration = KinematicCalibration::fit(&all, &ds.robot)?;
    let verdict = verdict(&table2, best);
    Ok(SweepReport {
        format: REPORT_FORMAT.to_string(),
        dataset_sha256: dataset_sha256.to_string(),
        n_samples: n,
        settings: settings.clone(),
        table1,
        best_hidden: best,
        table2,
        kinematic_calibration,
        warnings,
        verdict,
    })
}

/// Row of Table 2 by method name.
pub fn row<'a>(table2: &'a [MethodRow], name: &str) -> Option<&'a MethodRow> {
    table2.iter().find(|r| r.method == name)
}

fn verdict(t: &[MethodRow], best: usize) -> String {
    let name = net_method_name(best);
    let (Some(raw), Some(kin), Some(net)) = (row(t, RAW), row(t, KINEMATIC), row(t, &name)) else {
        return String::new();
    };
    let pct = |r: &MethodRow| 100.0 * r.rel_error.mean;
    let mut s = format!(
        "Cross-validated relative end-point error: raw odometry {:.2} %, kinematic calibration {:.2} %, {} {:.2} % ({:.0} % of raw). ",
        pct(raw),
        pct(kin),
        name,
        pct(net),
        100.0 * net.rel_error.mean / raw.rel_error.mean
    );
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
    if let Some(o) = row(t, ORACLE) {
        s += &format!(
            " The oracle with the true systematic parameters reaches {:.2} %; the perceptron is at {:.2}x the oracle, the kinematic calibration at {:.2}x.",
            pct(o),
            net.rel_error.mean / o.rel_error.mean,
            kin.rel_error.mean / o.rel_error.mean
        );
    }
    s
}
