//! Fitting the one model that `odocal train` writes: the perceptron on every sample (with its
//! early-stopping split), the metrics model.json records, the kinematic calibration beside it,
//! and, unless left out, a cross-validated estimate of the same configuration.

use std::collections::HashMap;

use odocal_dataset::{Dataset, OracleFile, Sample};

use crate::crossval::{assign_folds, derive_seed, net_method_name, row};
use crate::{
    report, sweep, train, KinematicCalibration, Metrics, ModelFile, ModelMetrics, SweepSettings,
    TrainError, TrainSettings,
};

/// A fitted model and what `odocal train` reports about it.
pub struct FittedModel {
    /// The model as model.json holds it.
    pub model: ModelFile,
    /// Trainable parameters of the net.
    pub n_params: usize,
    /// Samples the weights were fitted to (the rest is the early-stopping split).
    pub n_fit: usize,
    /// Table 2 of the cross-validated estimate (Markdown), when it was run.
    pub table2_markdown: Option<String>,
    /// Warnings for the user (capacity, no cross-validated estimate).
    pub warnings: Vec<String>,
}

/// The oracle's end point of every sample of `ds` from a synthetic experiment's truth;
/// `name` (the truth file) starts the error when a run is missing.
pub fn oracle_ends(
    ds: &Dataset,
    oracle: &OracleFile,
    name: &str,
) -> Result<HashMap<String, [f64; 2]>, TrainError> {
    let mut map = HashMap::new();
    for s in &ds.samples {
        let end = oracle.end_m(s).ok_or_else(|| {
            TrainError::Dataset(format!(
                "{name}: no entry for run '{}' of the dataset",
                s.run_id
            ))
        })?;
        map.insert(s.run_id.clone(), end);
    }
    Ok(map)
}

/// Fits one model with `ts` on every sample of `ds` (`sha` is the dataset's SHA-256). With
/// `cv_folds`, also estimates the configuration's error by one restart of cross-validation
/// over that many folds (`on_fold` is called after each fold); without, the model records no
/// cross-validated figures.
pub fn fit_model(
    ds: &Dataset,
    sha: &str,
    ts: &TrainSettings,
    seed: u64,
    cv_folds: Option<usize>,
    oracle: Option<&HashMap<String, [f64; 2]>>,
    on_fold: &(dyn Fn() + Sync),
) -> Result<FittedModel, TrainError> {
    let n = ds.samples.len();
    let mut warnings = Vec::new();
    let n_fit =
        n - ((n as f64 * ts.val_fraction).round() as usize).max(usize::from(ts.val_fraction > 0.0));
    if let Some(w) = crate::crossval::capacity_warning(ts.hidden, n_fit) {
        warnings.push(w);
    }
    let inputs: Vec<Vec<f64>> = ds.samples.iter().map(|s| s.inputs.clone()).collect();
    let targets: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.target_m).collect();
    let net = train(&inputs, &targets, ts, seed)?;
    if net.best_epoch == 0 && !net.validation_indices.is_empty() {
        // The starting weights are random: they put every end near the targets' mean, give
        // or take a random function of the log.
        warnings.push(format!(
            "no training step improved the early-stopping split's error over the starting weights (kept epoch 0, {}): the model is its random initialisation, which puts every run's end near the training runs' mean whatever the log says; try other seeds (--seed), or `--sweep` with --restarts to see how the net does across them",
            net.stop_reason
        ));
    }
    let all: Vec<&Sample> = ds.samples.iter().collect();
    let pred: Vec<[f64; 2]> = inputs.iter().map(|x| net.predict(x)).collect();
    let raw: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.raw_end_m).collect();

    // Fit and early-stopping validation samples reported separately.
    let subset = |idx: &[usize]| {
        let s: Vec<&Sample> = idx.iter().map(|&i| &ds.samples[i]).collect();
        let p: Vec<[f64; 2]> = idx.iter().map(|&i| pred[i]).collect();
        Metrics::of(&s, &p)
    };
    let train_metrics = subset(&net.fit_indices);
    let validation = (!net.validation_indices.is_empty()).then(|| subset(&net.validation_indices));
    let mut table2_markdown = None;
    let cross_validated = match cv_folds.map(|f| (f, assign_folds(&ds.samples, f, seed))) {
        None => None,
        Some((folds, Ok(_))) => {
            let s = SweepSettings {
                hidden_sizes: vec![ts.hidden],
                restarts: 1,
                folds,
                train: ts.clone(),
                seed: derive_seed(seed, &[0xC0]),
            };
            let rep = sweep(ds, sha, &s, oracle, on_fold)?;
            table2_markdown = Some(report::table2_markdown(&rep));
            warnings.extend(crate::crossval::no_better_than_the_mean(
                &rep.table2,
                &net_method_name(ts.hidden),
            ));
            let r = row(&rep.table2, &net_method_name(ts.hidden))
                .ok_or_else(|| TrainError::Numerical("cross-validation lost its row".into()))?;
            Some(Metrics {
                mse_m2: r.mse_m2.mean,
                mse_cm2: r.mse_m2.mean * 1e4,
                half_sse_m2: r.mse_m2.mean * n as f64,
                rel_error: r.rel_error.mean,
                rms_end_error_m: r.rms_end_error_m,
                n,
            })
        }
        Some((_, Err(e))) => {
            warnings.push(format!("no cross-validated estimate ({e})"));
            None
        }
    };
    let kin = KinematicCalibration::fit(&all, &ds.robot).ok();
    if let Some(k) = &kin {
        k.check_physical()?;
    }
    let metrics = ModelMetrics {
        train: train_metrics,
        validation,
        raw_odometry: Metrics::of(&all, &raw),
        cross_validated,
    };
    let mut model = ModelFile::new(&net, ts, seed, ds.robot, sha, n, metrics, kin);
    model.domain = crate::domain::TrainingDomain::of(&ds.samples);
    Ok(FittedModel {
        model,
        n_params: net.net.n_params(),
        n_fit: net.n_fit,
        table2_markdown,
        warnings,
    })
}

impl FittedModel {
    /// What `odocal train` prints about the model: one line per figure, each with its unit.
    pub fn summary(&self, folds: usize) -> Vec<String> {
        let m = &self.model;
        let mut out = vec![
            format!(
                "trained 18-{}-2 ({} parameters) with {:?} on {} samples ({} fitted): kept epoch {} ({}).",
                m.training.hidden,
                self.n_params,
                m.training.method,
                m.n_samples,
                self.n_fit,
                m.best_epoch,
                m.stop_reason
            ),
            format!(
                "fitted samples: MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} % (raw odometry on all samples {:.2} %).",
                m.metrics.train.mse_m2,
                m.metrics.train.mse_cm2,
                100.0 * m.metrics.train.rel_error,
                100.0 * m.metrics.raw_odometry.rel_error
            ),
        ];
        if let Some(v) = &m.metrics.validation {
            out.push(format!(
                "early-stopping split ({} samples): MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} %.",
                v.n,
                v.mse_m2,
                v.mse_cm2,
                100.0 * v.rel_error
            ));
        }
        if let Some(cv) = &m.metrics.cross_validated {
            out.push(format!(
                "cross-validated ({folds} folds): MSE {:.6} m² ({:.2} cm²), relative end-point error {:.2} %.",
                cv.mse_m2,
                cv.mse_cm2,
                100.0 * cv.rel_error
            ));
        }
        if let Some(k) = &m.kinematic_calibration {
            out.push(format!(
                "kinematic calibration: left_wheel_radius_multiplier {:.4}, right_wheel_radius_multiplier {:.4}, wheel_separation_multiplier {:.4}",
                k.ros.left_wheel_radius_multiplier, k.ros.right_wheel_radius_multiplier, k.ros.wheel_separation_multiplier
            ));
        }
        out
    }
}
