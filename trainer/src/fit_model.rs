//! Fitting the one model that `odocal train` writes: the perceptron on every sample (with its
//! early-stopping split), the metrics model.json records, the kinematic calibration beside it,
//! and, unless left out, a cross-validated estimate of the same configuration.

use std::collections::HashMap;

use odocal_dataset::{Dataset, OracleFile, Sample};

use crate::crossval::{assign_folds, derive_seed, net_method_name, row};
use crate::{
    report, sweep, train_runs, KinematicCalibration, Metrics, ModelFile, ModelMetrics,
    SweepSettings, TrainError, TrainSettings, TrainedNet,
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
    let net = train_runs(&inputs, &targets, ts, seed)?;
    let kept_start = kept_starting_weights(&net);
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
    let raw_subset = |idx: &[usize]| {
        let s: Vec<&Sample> = idx.iter().map(|&i| &ds.samples[i]).collect();
        let r: Vec<[f64; 2]> = idx.iter().map(|&i| raw[i]).collect();
        Metrics::of(&s, &r)
    };
    let raw_validation = raw_subset(&net.validation_indices);
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
    // Judged where the net was not fitted: the cross-validated estimate, else the split.
    let held_out = cross_validated
        .as_ref()
        .map(|m| ("cross-validated", m.rel_error, raw_odometry_error(ds)))
        .or_else(|| {
            validation.as_ref().map(|m| {
                (
                    "on the early-stopping split",
                    m.rel_error,
                    raw_validation.rel_error,
                )
            })
        });
    warnings.splice(0..0, usefulness_warning(kept_start, held_out));
    warnings.extend(stopped_at_the_cap(&net, ts.max_epochs));
    let kin = KinematicCalibration::fit(&all, &ds.robot).ok();
    if let Some(k) = &kin {
        k.check_physical()?;
        let r = &k.ros;
        let fitted = odocal_dataset::WheelGeometry {
            left_wheel_diameter_m: r.left_wheel_radius_multiplier * ds.robot.wheel_diameter_m,
            right_wheel_diameter_m: r.right_wheel_radius_multiplier * ds.robot.wheel_diameter_m,
            wheel_base_m: r.wheel_separation_multiplier * ds.robot.wheel_base_m,
        };
        // Straight runs do not fit a wheel base (a prior holds it near nominal).
        warnings.extend(crate::baseline::unlike_nominal_warning(
            &fitted, &ds.robot, false,
        ));
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

/// Which net kept its random starting weights (epoch 0 best on the early-stopping split):
/// "" for the one net, "for runs driven forwards"/"backwards" when there are two.
fn kept_starting_weights(net: &TrainedNet) -> Vec<&'static str> {
    nets_where(net, |n| {
        n.best_epoch == 0 && !n.validation_indices.is_empty()
    })
}

/// The nets of `net` for which `test` holds, named as [`kept_starting_weights`] names them.
fn nets_where(net: &TrainedNet, test: impl Fn(&TrainedNet) -> bool) -> Vec<&'static str> {
    match &net.backward {
        None => test(net).then_some("").into_iter().collect(),
        Some(b) => [
            (net, "for runs driven forwards"),
            (b.as_ref(), "for runs driven backwards"),
        ]
        .into_iter()
        .filter(|(n, _)| test(n))
        .map(|(_, way)| way)
        .collect(),
    }
}

/// A net whose kept epoch is the last the cap allowed was still improving when training
/// stopped: said, since its figures are those of an unfinished fit.
fn stopped_at_the_cap(net: &TrainedNet, max_epochs: usize) -> Option<String> {
    let ways = nets_where(net, |n| n.best_epoch >= max_epochs);
    (!ways.is_empty()).then(|| {
        let which = ways.join(" and ");
        format!(
            "training stopped at its cap of {max_epochs} epochs{}{which} while the net was still improving: the model is not fully trained; give a larger --max-epochs (the default stops on the early-stopping split, not on a cap)",
            if which.is_empty() { "" } else { " " }
        )
    })
}

fn raw_odometry_error(ds: &Dataset) -> f64 {
    let raw: Vec<[f64; 2]> = ds.samples.iter().map(|s| s.raw_end_m).collect();
    Metrics::of(&ds.samples.iter().collect::<Vec<_>>(), &raw).rel_error
}

/// A model whose error on runs it was not fitted to is no lower than raw odometry's corrects
/// nothing: said first and plainly, with the figures, whatever the epoch. A net that kept its
/// random starting weights (`kept_start` names which) is said so too; it puts every run's
/// end near the training runs' mean whatever the log says. `held_out`: where it was judged,
/// its relative error and raw odometry's on the same runs.
fn usefulness_warning(kept_start: Vec<&str>, held_out: Option<(&str, f64, f64)>) -> Vec<String> {
    let start = |ways: &[&str]| {
        ways.iter()
            .map(|w| {
                format!(
                    "kept epoch 0{}",
                    if w.is_empty() {
                        String::new()
                    } else {
                        format!(" {w}")
                    }
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match held_out {
        Some((where_, model, raw)) if model >= raw => vec![format!(
            "THE MODEL IS USELESS: its relative end-point error {where_} is {:.2} %, no better than raw odometry's {:.2} % on the same runs{}; do not use it to correct logs. Check the dataset (`odocal dataset` lists rejected runs and notes), try other seeds (--seed) or `--sweep` with --restarts to see how the net does across them",
            100.0 * model,
            100.0 * raw,
            if kept_start.is_empty() {
                String::new()
            } else {
                format!(" (training {}: the model is its random initialisation)", start(&kept_start))
            }
        )],
        _ if !kept_start.is_empty() => vec![format!(
            "no training step improved the early-stopping split's error over the starting weights ({}): the model is its random initialisation, which puts every run's end near the training runs' mean whatever the log says; try other seeds (--seed), or `--sweep` with --restarts to see how the net does across them",
            start(&kept_start)
        )],
        _ => Vec::new(),
    }
}

impl FittedModel {
    /// What `odocal train` prints about the model: one line per figure, each with its unit.
    pub fn summary(&self, folds: usize) -> Vec<String> {
        let m = &self.model;
        let trained = match &m.backward_net {
            None => format!(
                "trained 18-{}-2 ({} parameters) with {:?} on {} samples ({} fitted): kept epoch {} ({}).",
                m.training.hidden,
                self.n_params,
                m.training.method,
                m.n_samples,
                self.n_fit,
                m.best_epoch,
                m.stop_reason
            ),
            Some(b) => format!(
                "trained two 18-{}-2 nets ({} parameters each) with {:?} on {} samples ({} fitted), one per direction of travel: {} runs driven forwards, kept epoch {} ({}); {} driven backwards, kept epoch {} ({}).",
                m.training.hidden,
                self.n_params,
                m.training.method,
                m.n_samples,
                self.n_fit,
                m.n_samples - b.n_samples,
                m.best_epoch,
                m.stop_reason,
                b.n_samples,
                b.best_epoch,
                b.stop_reason
            ),
        };
        let mut out = vec![
            trained,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A net that kept its starting weights and corrects nothing used to be reported as
    /// "kept epoch 0" alone, among the capacity and mean-end warnings; it leads now, plainly.
    #[test]
    fn a_model_no_better_than_raw_odometry_is_called_useless() {
        let w = usefulness_warning(
            vec!["for runs driven backwards"],
            Some(("cross-validated", 0.30, 0.095)),
        );
        assert_eq!(w.len(), 1);
        assert!(w[0].starts_with("THE MODEL IS USELESS"), "{}", w[0]);
        for figure in [
            "30.00 %",
            "9.50 %",
            "kept epoch 0 for runs driven backwards",
        ] {
            assert!(w[0].contains(figure), "{figure}: {}", w[0]);
        }
        let w = usefulness_warning(
            Vec::new(),
            Some(("on the early-stopping split", 0.12, 0.10)),
        );
        assert!(
            w[0].starts_with("THE MODEL IS USELESS") && !w[0].contains("epoch 0"),
            "{}",
            w[0]
        );
        // Epoch 0 better than raw odometry: the milder warning; neither: none.
        let w = usefulness_warning(vec![""], Some(("cross-validated", 0.045, 0.095)));
        assert!(
            w[0].starts_with("no training step") && w[0].contains("(kept epoch 0)"),
            "{}",
            w[0]
        );
        assert!(usefulness_warning(Vec::new(), Some(("cross-validated", 0.045, 0.095))).is_empty());
    }
}
