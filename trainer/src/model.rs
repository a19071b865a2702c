//! model.json: the trained corrector with everything needed to apply it safely.

use nalgebra::{DMatrix, DVector};
use odocal_dataset::{RobotParams, FEATURE_RULE, N_INPUTS};
use serde::{Deserialize, Serialize};

use crate::baseline::KinematicCalibration;
use crate::error::TrainError;
use crate::metrics::Metrics;
use crate::net::{Normalisation, Perceptron};
use crate::train::{TrainSettings, TrainedNet};

/// The `format` tag of model files.
pub const MODEL_FORMAT: &str = "odocal.model/1";

/// The fewest runs an early-stopping split needs for its error to stand for the model's on
/// runs it was not fitted to (one or two runs say little either way).
pub const MIN_SPLIT_FOR_ESTIMATE: usize = 10;

/// Weights of the perceptron; matrices as rows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Weights {
    /// Hidden weights, k rows of 18.
    pub w1: Vec<Vec<f64>>,
    /// Hidden biases, k.
    pub b1: Vec<f64>,
    /// Output weights, 2 rows of k.
    pub w2: Vec<Vec<f64>>,
    /// Output biases, 2.
    pub b2: Vec<f64>,
}

/// The net of runs driven backwards, beside the forward runs' net of a model trained on runs
/// driven both ways (see [`crate::train_runs`]); same layer sizes and activations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BackwardNet {
    /// Runs driven backwards in the dataset (its fitted runs and early-stopping split).
    pub n_samples: usize,
    /// Weights acting on normalised inputs.
    pub weights: Weights,
    /// Input normalisation of the backward runs.
    pub input_normalisation: Normalisation,
    /// Output normalisation of the backward runs.
    pub output_normalisation: Normalisation,
    /// Epoch whose weights were kept.
    pub best_epoch: usize,
    /// Why training stopped.
    pub stop_reason: String,
}

/// Metrics recorded with a model (all MSE per coordinate, m^2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelMetrics {
    /// On the samples the weights were fitted on.
    pub train: Metrics,
    /// On the early-stopping validation split (None without one).
    pub validation: Option<Metrics>,
    /// Raw odometry on all samples, for comparison.
    pub raw_odometry: Metrics,
    /// Cross-validated estimate of this configuration (k folds, one restart), if run.
    pub cross_validated: Option<Metrics>,
}

/// Contents of model.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// Always [`MODEL_FORMAT`].
    pub format: String,
    /// Feature rule the inputs must follow.
    pub feature_rule: String,
    /// Robot parameters the training logs were dead-reckoned with.
    pub robot: RobotParams,
    /// SHA-256 of the dataset file trained on.
    pub dataset_sha256: String,
    /// Samples in that dataset.
    pub n_samples: usize,
    /// Layer sizes [18, k, 2].
    pub layer_sizes: [usize; 3],
    /// Activation functions, for readers: hidden, output.
    pub activations: [String; 2],
    /// Weights acting on normalised inputs (of the forward runs when `backward_net` is given).
    pub weights: Weights,
    /// Input normalisation: x_n = (x - offset) * scale.
    pub input_normalisation: Normalisation,
    /// Output normalisation: y = offset + y_n / scale (x, y end position, metres).
    pub output_normalisation: Normalisation,
    /// Training settings.
    pub training: TrainSettings,
    /// Seed of the training.
    pub seed: u64,
    /// Epoch whose weights were kept.
    pub best_epoch: usize,
    /// Why training stopped.
    pub stop_reason: String,
    /// Metrics.
    pub metrics: ModelMetrics,
    /// Kinematic calibration fitted on the same dataset (reference / ROS export).
    pub kinematic_calibration: Option<KinematicCalibration>,
    /// What the model was trained on; logs outside it are refused by `odocal correct`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub domain: Option<crate::domain::TrainingDomain>,
    /// The net of runs driven backwards, when the dataset had runs driven both ways.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backward_net: Option<BackwardNet>,
}

fn weights_of(net: &Perceptron) -> Weights {
    Weights {
        w1: rows(&net.w1),
        b1: net.b1.iter().copied().collect(),
        w2: rows(&net.w2),
        b2: net.b2.iter().copied().collect(),
    }
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|r| m.row(r).iter().copied().collect())
        .collect()
}

fn matrix(rows: &[Vec<f64>], nr: usize, nc: usize, what: &str) -> Result<DMatrix<f64>, TrainError> {
    if rows.len() != nr || rows.iter().any(|r| r.len() != nc) {
        return Err(TrainError::Model(format!("{what} must be {nr} x {nc}")));
    }
    Ok(DMatrix::from_fn(nr, nc, |r, c| rows[r][c]))
}

impl ModelFile {
    /// Packs a trained net with its provenance.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        net: &TrainedNet,
        settings: &TrainSettings,
        seed: u64,
        robot: RobotParams,
        dataset_sha256: &str,
        n_samples: usize,
        metrics: ModelMetrics,
        kinematic_calibration: Option<KinematicCalibration>,
    ) -> Self {
        Self {
            format: MODEL_FORMAT.to_string(),
            feature_rule: FEATURE_RULE.to_string(),
            robot,
            dataset_sha256: dataset_sha256.to_string(),
            n_samples,
            layer_sizes: [net.net.n_in(), net.net.hidden(), net.net.n_out()],
            activations: ["logistic sigmoid".into(), "linear".into()],
            weights: weights_of(&net.net),
            input_normalisation: net.input_norm.clone(),
            output_normalisation: net.output_norm.clone(),
            training: settings.clone(),
            seed,
            best_epoch: net.best_epoch,
            stop_reason: net.stop_reason.clone(),
            metrics,
            kinematic_calibration,
            domain: None,
            backward_net: net.backward.as_ref().map(|b| BackwardNet {
                n_samples: b.n_fit + b.validation_indices.len(),
                weights: weights_of(&b.net),
                input_normalisation: b.input_norm.clone(),
                output_normalisation: b.output_norm.clone(),
                best_epoch: b.best_epoch,
                stop_reason: b.stop_reason.clone(),
            }),
        }
    }

    /// A warning when the file carries no training domain: logs outside it cannot be named.
    pub fn no_domain_warning(&self, name: &str) -> Option<String> {
        match &self.domain {
            None => Some(format!(
                "{name} carries no training domain (written by an older odocal, or edited): a log unlike the runs it was trained on (driven backwards, longer, faster) is corrected without being named as outside it; train it again to have such logs named"
            )),
            Some(d) if d.duration_s.is_none() => Some(format!(
                "{name}: its training domain has no domain.duration_s (written by an older odocal, or edited): a run at a speed the training never drove is corrected without being named as outside it; train it again to have such runs named"
            )),
            Some(_) => None,
        }
    }

    /// A warning when training kept a net's random initialisation (epoch 0, which `train`
    /// named when it wrote the file): that net's corrections are no better than chance.
    pub fn untrained_warning(&self, name: &str) -> Option<String> {
        let forward = self.best_epoch == 0;
        let backward = self
            .backward_net
            .as_ref()
            .is_some_and(|b| b.best_epoch == 0);
        let which = match (forward, backward, self.backward_net.is_some()) {
            (true, true, _) | (true, false, false) => "its net",
            (true, false, true) => "its net of runs driven forwards",
            (false, true, _) => "its net of runs driven backwards",
            (false, false, _) => return None,
        };
        Some(format!(
            "{name}: {which} kept epoch 0, its random initialisation (no epoch of training bettered it on the validation runs): its corrections are no better than chance; train again with more runs or another --seed, and use the model when `train` no longer names epoch 0"
        ))
    }

    /// How well the model corrects runs it was not fitted to, as recorded by `train`: its
    /// cross-validated relative end-point error, else its early-stopping split's when that
    /// holds at least [`MIN_SPLIT_FOR_ESTIMATE`] runs. `Ok((error, where))`, a fraction and
    /// where it was measured; `Err` with a warning when neither is there.
    pub fn held_out_error(&self, name: &str) -> Result<(f64, String), String> {
        let m = &self.metrics;
        if let Some(cv) = &m.cross_validated {
            return Ok((cv.rel_error, format!("cross-validated over {} runs", cv.n)));
        }
        match &m.validation {
            Some(v) if v.n >= MIN_SPLIT_FOR_ESTIMATE => Ok((
                v.rel_error,
                format!("on its early-stopping split of {} runs", v.n),
            )),
            v => Err(format!(
                "{name}: no estimate of how well it corrects runs it was not fitted to ({}, no cross-validation): its correction may be worse than raw odometry unseen; train it with cross-validation (without --no-cv), on more runs",
                v.map_or("no early-stopping split".to_string(), |v| format!(
                    "an early-stopping split of {} run{}",
                    v.n,
                    if v.n == 1 { "" } else { "s" }
                ))
            )),
        }
    }

    /// Reads model.json (see [`ModelFile::parse`]).
    pub fn read(path: &std::path::Path) -> Result<Self, TrainError> {
        let text = odocal_core::read_text(path)?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses model.json text (`name` starts every message), rejecting other formats,
    /// inconsistent sizes, non-finite weights and robot parameters without physical sense.
    pub fn parse(text: &str, name: &str) -> Result<Self, TrainError> {
        let m: ModelFile = odocal_core::parse_tagged_json(
            text,
            name,
            MODEL_FORMAT,
            "pass a model.json that `odocal train` writes from a dataset of straight runs (a path model, odocal.path-model/1, from a window dataset, is judged with `odocal evaluate`), or retrain with this build",
        )?;
        m.robot
            .check()
            .map_err(|e| TrainError::Model(format!("{name}: robot.{e}")))?;
        m.to_net().map_err(|e| e.in_model_file(name))?;
        m.check_sense()
            .map_err(|e| TrainError::Model(format!("{name}: {e}; retrain the model")))?;
        Ok(m)
    }

    /// What a hand edit can break that the sizes do not show: activations this build does not
    /// compute, a normalisation that divides by zero, a domain whose ranges run backwards.
    fn check_sense(&self) -> Result<(), String> {
        let expected = ["logistic sigmoid", "linear"];
        for (i, (a, e)) in self.activations.iter().zip(expected).enumerate() {
            if a != e {
                return Err(format!(
                    "activations[{i}] is \"{a}\", but this build computes \"{e}\" there"
                ));
            }
        }
        // A scale is 1 / the training's spread: 0 only for an input column that never
        // varied, never for an output, whose 0 would put every corrected end at one point.
        if let Some(i) = self.input_normalisation.scale.iter().position(|&v| v < 0.0) {
            return Err(format!(
                "input_normalisation.scale[{i}] is negative; a scale is 1 / the training's spread"
            ));
        }
        let outputs = std::iter::once(("", &self.output_normalisation)).chain(
            self.backward_net
                .iter()
                .map(|b| ("backward_net.", &b.output_normalisation)),
        );
        for (part, norm) in outputs {
            if let Some(i) = norm.scale.iter().position(|&v| v <= 0.0) {
                return Err(format!(
                    "{part}output_normalisation.scale[{i}] = {} must be > 0 (1 / the targets' spread; 0 would put every corrected end point at one place)",
                    norm.scale[i]
                ));
            }
        }
        if let Some(d) = &self.domain {
            if d.input_min.len() != self.layer_sizes[0] || d.input_max.len() != self.layer_sizes[0]
            {
                return Err(format!(
                    "domain.input_min and input_max must hold {} values each",
                    self.layer_sizes[0]
                ));
            }
            for (i, (a, b)) in d.input_min.iter().zip(&d.input_max).enumerate() {
                if !(a.is_finite() && b.is_finite() && a <= b) {
                    return Err(format!(
                        "domain.input_min[{i}] = {a} is not at most input_max[{i}] = {b}"
                    ));
                }
            }
            let [p0, p1] = d.end_distance_m;
            if !(p0.is_finite() && p1.is_finite() && 0.0 <= p0 && p0 <= p1) {
                return Err(format!(
                    "domain.end_distance_m = [{p0}, {p1}] must be two distances, metres, shortest first"
                ));
            }
            // Reversed, every run was refused as "a speed the training did not drive".
            if let Some([t0, t1]) = d.duration_s {
                if !(t0.is_finite() && t1.is_finite() && 0.0 < t0 && t0 <= t1) {
                    return Err(format!(
                        "domain.duration_s = [{t0}, {t1}] must be two run durations, seconds, shortest first"
                    ));
                }
            }
            // A scale of 0 is written for an input the training never varied; on one it
            // varied, the net reads that input as constant, whatever the log says.
            let varied = d.input_min.iter().zip(&d.input_max).map(|(a, b)| a < b);
            if let Some(i) = self
                .input_normalisation
                .scale
                .iter()
                .zip(varied)
                .position(|(&v, varied)| v == 0.0 && varied)
            {
                return Err(format!(
                    "input_normalisation.scale[{i}] = 0, but the training's input {i} ranged from {} to {} (a scale is 1 / its spread)",
                    d.input_min[i], d.input_max[i]
                ));
            }
        }
        Ok(())
    }

    /// Rebuilds the trained net (checks sizes and finiteness).
    pub fn to_net(&self) -> Result<TrainedNet, TrainError> {
        let [n, _, o] = self.layer_sizes;
        if n != N_INPUTS || o != 2 {
            return Err(TrainError::Model(format!(
                "layer sizes {:?}: expected [{N_INPUTS}, k, 2]",
                self.layer_sizes
            )));
        }
        let backward = match &self.backward_net {
            Some(b) => Some(Box::new(
                self.net_of(
                    &b.weights,
                    &b.input_normalisation,
                    &b.output_normalisation,
                    b.best_epoch,
                    &b.stop_reason,
                    b.n_samples,
                )
                .map_err(|e| TrainError::Model(format!("backward_net: {e}")))?,
            )),
            None => None,
        };
        let mut net = self.net_of(
            &self.weights,
            &self.input_normalisation,
            &self.output_normalisation,
            self.best_epoch,
            &self.stop_reason,
            self.n_samples,
        )?;
        net.backward = backward;
        Ok(net)
    }

    /// One net of the model's layer sizes from its weights and normalisations.
    fn net_of(
        &self,
        w: &Weights,
        input_normalisation: &Normalisation,
        output_normalisation: &Normalisation,
        best_epoch: usize,
        stop_reason: &str,
        n_samples: usize,
    ) -> Result<TrainedNet, TrainError> {
        let [n, k, o] = self.layer_sizes;
        let net = Perceptron {
            w1: matrix(&w.w1, k, n, "weights.w1")?,
            b1: DVector::from_vec(w.b1.clone()),
            w2: matrix(&w.w2, o, k, "weights.w2")?,
            b2: DVector::from_vec(w.b2.clone()),
        };
        if net.b1.len() != k || net.b2.len() != o {
            return Err(TrainError::Model(
                "bias lengths do not match layer sizes".into(),
            ));
        }
        let norms = [(input_normalisation, n), (output_normalisation, o)];
        for (nm, len) in norms {
            if nm.offset.len() != len || nm.scale.len() != len {
                return Err(TrainError::Model(
                    "normalisation length does not match layer sizes".into(),
                ));
            }
        }
        let all_finite = net.to_params().iter().all(|v| v.is_finite())
            && norms
                .iter()
                .all(|(nm, _)| nm.offset.iter().chain(&nm.scale).all(|v| v.is_finite()));
        if !all_finite {
            return Err(TrainError::Model(
                "weights or normalisation contain NaN/inf".into(),
            ));
        }
        Ok(TrainedNet {
            net,
            input_norm: input_normalisation.clone(),
            output_norm: output_normalisation.clone(),
            best_epoch,
            epochs_run: best_epoch,
            stop_reason: stop_reason.to_string(),
            n_fit: n_samples,
            fit_indices: Vec::new(),
            validation_indices: Vec::new(),
            backward: None,
        })
    }

    /// Refuses features built with another rule or logs of another robot.
    pub fn check_compatible(
        &self,
        feature_rule: &str,
        robot: &RobotParams,
    ) -> Result<(), TrainError> {
        if self.feature_rule != feature_rule {
            return Err(TrainError::Model(format!(
                "model was trained on feature rule '{}', but the inputs follow '{}'",
                self.feature_rule, feature_rule
            )));
        }
        crate::domain::check_same_robot(&self.robot, robot, "the log")?;
        Ok(())
    }

    /// Corrected end point (metres, run start frame) for 18 inputs built with the model's rule.
    pub fn correct(&self, inputs: &[f64]) -> Result<[f64; 2], TrainError> {
        if inputs.len() != N_INPUTS {
            return Err(TrainError::Model(format!(
                "{} inputs, the model takes {N_INPUTS}",
                inputs.len()
            )));
        }
        if inputs.iter().any(|v| !v.is_finite()) {
            return Err(TrainError::Model("inputs contain NaN/inf".into()));
        }
        Ok(self.to_net()?.predict(inputs))
    }
}
