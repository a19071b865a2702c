//! Training of the perceptron: Levenberg–Marquardt (default, analytic Jacobian,
//! the `levenberg-marquardt` crate) or back-propagation with momentum; early
//! stopping on a validation split, optional weight decay, deterministic per seed.

use std::cell::RefCell;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector};
use nalgebra::{Dyn, Owned};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use odocal_dataset::N_INPUTS;

use crate::error::TrainError;
use crate::net::{Normalisation, Perceptron};

/// Smallest and largest hidden-layer size accepted.
pub const HIDDEN_RANGE: std::ops::RangeInclusive<usize> = 1..=64;

/// Default weight decay (normalised units): none. On odocal's robot simulator early
/// stopping alone generalises as well (131 runs, seed 1, 5 folds x 10 restarts: 4.41 % vs
/// 4.36 % with decay 0.3; trainer/tests seeds 7 and 11 on a par with the oracle), and in LM
/// decay costs one extra residual row per weight (160 rows beside 222 for 18-8-2), which
/// nearly doubles the crate's QR per epoch (sweep 10.0 s instead of 17.1 s wall on 2 cores).
pub const DEFAULT_WEIGHT_DECAY: f64 = 0.0;

/// Largest weight decay taken: each sample's normalised residuals are of order 1, so a
/// penalty this heavy outweighs the fit of any dataset odocal trains on.
pub const MAX_WEIGHT_DECAY: f64 = 1000.0;

/// LM early stopping: epochs without validation improvement before stopping. MATLAB's
/// trainlm uses 6; with ~20 validation runs the best epoch is typically 1-3, and 6 spent
/// 4 more QR factorisations per training for the same cross-validated error (131-run
/// experiment: 4.37 % with 6, 4.39 % with 2; tests' simulator: 1.24x vs 1.19x the oracle).
/// 1 was cheaper again but stopped too early on the tests' simulator (1.3-1.7x the oracle).
pub const LM_MAX_FAIL: usize = 2;

/// LM early stopping: a validation error less than 3 % below the best so far counts as a
/// failed epoch (as Keras' `min_delta`). The sum of squares over ~20 validation runs has a
/// standard error of ~20 %, so such gains are noise; they kept slow trainings running
/// (131-run experiment: same error, about 10 % less time in the sweep).
pub const LM_MIN_IMPROVEMENT: f64 = 0.03;

/// Initial trust region of LM as a multiple of the weight norm (MINPACK's `factor`, the
/// crate's `stepbound`). MINPACK's 100 lets the first steps of a freshly initialised net
/// overshoot and be rejected; 1 saves those evaluations at equal or lower error. The
/// damping is the identity, as in MATLAB's trainlm (the crate's `scale_diag` off): the
/// inputs are normalised, and on the tests' simulator it took 10 epochs instead of 14 and
/// reached 1.17x the oracle instead of 1.2x (131-run experiment: same error, ~7 % more
/// CPU time in the sweep).
pub const LM_STEP_BOUND: f64 = 1.0;

/// Training algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Levenberg–Marquardt of the `levenberg-marquardt` crate (MINPACK trust region, pivoted QR).
    Lm,
    /// Batch gradient descent with momentum (the source's back-propagation).
    Backprop,
}

impl std::str::FromStr for Method {
    type Err = TrainError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "lm" => Ok(Method::Lm),
            "backprop" | "bp" => Ok(Method::Backprop),
            _ => Err(TrainError::Settings(format!(
                "unknown method '{s}': use 'lm' or 'backprop'"
            ))),
        }
    }
}

/// Settings of one training.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainSettings {
    /// Hidden-layer size k.
    pub hidden: usize,
    /// Training algorithm.
    pub method: Method,
    /// Fraction of the training samples held out for early stopping (0 disables it).
    pub val_fraction: f64,
    /// Early stopping: epochs without validation improvement before stopping.
    pub max_fail: usize,
    /// Early stopping: relative decrease of the best validation error below which an
    /// epoch still counts as failed (0: any decrease counts as an improvement).
    #[serde(default)]
    pub min_improvement: f64,
    /// Upper bound on epochs.
    pub max_epochs: usize,
    /// Weight decay: adds lambda * sum(w^2) / 2 over the weights (not biases), normalised units.
    pub weight_decay: f64,
    /// Back-propagation learning rate (on the mean error in normalised units).
    pub learning_rate: f64,
    /// Back-propagation momentum.
    pub momentum: f64,
}

impl TrainSettings {
    /// Defaults for `method`: 15 % validation split; LM stops after [`LM_MAX_FAIL`] epochs
    /// without an improvement of [`LM_MIN_IMPROVEMENT`], back-propagation after 200 without
    /// any improvement; weight decay [`DEFAULT_WEIGHT_DECAY`].
    pub fn new(hidden: usize, method: Method) -> Self {
        match method {
            Method::Lm => Self {
                hidden,
                method,
                val_fraction: 0.15,
                max_fail: LM_MAX_FAIL,
                min_improvement: LM_MIN_IMPROVEMENT,
                max_epochs: 200,
                weight_decay: DEFAULT_WEIGHT_DECAY,
                learning_rate: 0.0,
                momentum: 0.0,
            },
            Method::Backprop => Self {
                hidden,
                method,
                val_fraction: 0.15,
                max_fail: 200,
                min_improvement: 0.0,
                max_epochs: 20_000,
                weight_decay: DEFAULT_WEIGHT_DECAY,
                learning_rate: 0.05,
                momentum: 0.9,
            },
        }
    }

    /// Checks the ranges of all settings.
    pub fn validate(&self) -> Result<(), TrainError> {
        if !HIDDEN_RANGE.contains(&self.hidden) {
            return Err(TrainError::Settings(format!(
                "hidden size k = {} is outside {}..={}",
                self.hidden,
                HIDDEN_RANGE.start(),
                HIDDEN_RANGE.end()
            )));
        }
        if !(0.0..0.5).contains(&self.val_fraction) {
            return Err(TrainError::Settings(format!(
                "validation fraction {} must be in [0, 0.5)",
                self.val_fraction
            )));
        }
        if !(self.weight_decay >= 0.0 && self.weight_decay <= MAX_WEIGHT_DECAY) {
            return Err(TrainError::Settings(format!(
                "weight decay {} must be between 0 and {MAX_WEIGHT_DECAY} (normalised units; a heavier penalty holds every weight at zero, a model that predicts the training's mean end whatever the log says)",
                self.weight_decay
            )));
        }
        if self.max_epochs == 0 {
            return Err(TrainError::Settings("max_epochs must be at least 1".into()));
        }
        if self.max_fail == 0 {
            return Err(TrainError::Settings("max_fail must be at least 1".into()));
        }
        if !(0.0..1.0).contains(&self.min_improvement) {
            return Err(TrainError::Settings(format!(
                "min_improvement {} must be in [0, 1)",
                self.min_improvement
            )));
        }
        Ok(())
    }
}

/// A trained net with its normalisation and training record.
#[derive(Debug, Clone)]
pub struct TrainedNet {
    /// The weights (acting on normalised inputs, producing normalised outputs).
    pub net: Perceptron,
    /// Input normalisation.
    pub input_norm: Normalisation,
    /// Output normalisation.
    pub output_norm: Normalisation,
    /// Epoch whose weights were kept (best validation error).
    pub best_epoch: usize,
    /// Epochs run in total.
    pub epochs_run: usize,
    /// Why training stopped.
    pub stop_reason: String,
    /// Number of samples the weights were fitted on (excluding the validation split).
    pub n_fit: usize,
    /// Indices (into the training rows) of the samples the weights were fitted on.
    pub fit_indices: Vec<usize>,
    /// Indices (into the training rows) of the early-stopping validation split.
    pub validation_indices: Vec<usize>,
    /// The net of runs driven backwards when the training had runs driven both ways
    /// ([`train_runs`]); this net then predicts the forward runs only. Its indices are into
    /// its own direction's rows.
    pub backward: Option<Box<TrainedNet>>,
}

impl TrainedNet {
    /// Predicted end position (metres) for one raw input row.
    pub fn predict(&self, inputs: &[f64]) -> [f64; 2] {
        match &self.backward {
            Some(b) if drives_backwards(inputs) => b.predict_one(inputs),
            _ => self.predict_one(inputs),
        }
    }

    fn predict_one(&self, inputs: &[f64]) -> [f64; 2] {
        let x: Vec<f64> = inputs
            .iter()
            .enumerate()
            .map(|(c, v)| self.input_norm.forward(c, *v))
            .collect();
        let mut y = [0.0; 2];
        self.net.forward(&x, &mut y);
        [
            self.output_norm.inverse(0, y[0]),
            self.output_norm.inverse(1, y[1]),
        ]
    }
}

/// Normalised design matrices for a subset of samples.
fn matrices(
    idx: &[usize],
    inputs: &[Vec<f64>],
    targets: &[[f64; 2]],
    inorm: &Normalisation,
    onorm: &Normalisation,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let n_in = inorm.offset.len();
    let xs = DMatrix::from_fn(idx.len(), n_in, |r, c| inorm.forward(c, inputs[idx[r]][c]));
    let ts = DMatrix::from_fn(idx.len(), 2, |r, c| onorm.forward(c, targets[idx[r]][c]));
    (xs, ts)
}

/// Output scale with a guard: a constant target column keeps unit scale.
fn output_norm(rows: &[&[f64]]) -> Normalisation {
    let mut n = Normalisation::fit(rows);
    for s in n.scale.iter_mut() {
        if *s == 0.0 {
            *s = 1.0;
        }
    }
    n
}

/// Bookkeeping of early stopping, shared by both methods.
#[derive(Debug, Clone)]
struct EarlyStop {
    epoch: usize,
    best_epoch: usize,
    best_val: f64,
    best_params: DVector<f64>,
    fails: usize,
    reason: Option<String>,
}

impl EarlyStop {
    fn new(p: DVector<f64>) -> Self {
        Self {
            epoch: 0,
            best_epoch: 0,
            best_val: f64::INFINITY,
            best_params: p,
            fails: 0,
            reason: None,
        }
    }

    /// Records the state after an epoch; returns false when training must stop.
    fn check(&mut self, val_err: Option<f64>, p: &DVector<f64>, s: &TrainSettings) -> bool {
        match val_err {
            Some(v) if v.is_finite() => {
                // Only an improvement by more than `min_improvement` resets the patience;
                // the best weights are kept on any improvement.
                if v < self.best_val * (1.0 - s.min_improvement) {
                    self.fails = 0;
                } else {
                    self.fails += 1;
                }
                if v < self.best_val {
                    self.best_val = v;
                    self.best_epoch = self.epoch;
                    self.best_params.copy_from(p);
                }
            }
            Some(_) => {
                self.reason = Some("validation error not finite".into());
                return false;
            }
            None => {
                self.best_epoch = self.epoch;
                self.best_params.copy_from(p);
            }
        }
        if self.fails >= s.max_fail {
            self.reason = Some(format!(
                "validation error did not improve in {} epochs",
                s.max_fail
            ));
            return false;
        }
        if self.epoch >= s.max_epochs {
            self.reason = Some(format!("reached {} epochs", s.max_epochs));
            return false;
        }
        self.epoch += 1;
        true
    }
}

/// Why the LM crate stopped, in words (its Debug text read "Converged { ftol: false, xtol:
/// true }").
fn converged_why(t: &TerminationReason) -> String {
    match t {
        TerminationReason::Converged {
            ftol: true,
            xtol: true,
        } => "the error and the weights stopped changing".into(),
        TerminationReason::Converged { ftol: true, .. } => "the error stopped falling".into(),
        TerminationReason::Converged { .. } => "the weights stopped changing".into(),
        TerminationReason::ResidualsZero => "the fit is exact".into(),
        TerminationReason::Orthogonal => "the gradient vanished".into(),
        TerminationReason::LostPatience => "its evaluation budget ran out".into(),
        TerminationReason::NoImprovementPossible(what) => format!("no step improves {what}"),
        other => format!("{other:?}"),
    }
}

/// Sum of squared residuals of `net` on (xs, ts), normalised units.
fn sse(net: &Perceptron, xs: &DMatrix<f64>, ts: &DMatrix<f64>) -> f64 {
    let mut res = vec![0.0; xs.nrows() * ts.ncols()];
    net.residuals_and_jacobian(xs, ts, &mut res, None);
    res.iter().map(|r| r * r).sum()
}

/// The least-squares problem handed to the LM crate.
struct NetProblem<'a> {
    net: Perceptron,
    xs: &'a DMatrix<f64>,
    ts: &'a DMatrix<f64>,
    val: Option<(&'a DMatrix<f64>, &'a DMatrix<f64>)>,
    decay_sqrt: f64,
    weight_idx: Vec<usize>,
    settings: &'a TrainSettings,
    stop: RefCell<EarlyStop>,
}

impl NetProblem<'_> {
    fn n_res(&self) -> usize {
        let decay_rows = if self.decay_sqrt > 0.0 {
            self.weight_idx.len()
        } else {
            0
        };
        self.xs.nrows() * self.ts.ncols() + decay_rows
    }

    fn val_err(&self) -> Option<f64> {
        self.val.map(|(vx, vt)| sse(&self.net, vx, vt))
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for NetProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.net.set_params(x);
    }

    fn params(&self) -> DVector<f64> {
        self.net.to_params()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let mut r = DVector::zeros(self.n_res());
        let base = self.xs.nrows() * self.ts.ncols();
        self.net
            .residuals_and_jacobian(self.xs, self.ts, &mut r.as_mut_slice()[..base], None);
        if self.decay_sqrt > 0.0 {
            let p = self.net.to_params();
            for (row, &i) in self.weight_idx.iter().enumerate() {
                r[base + row] = self.decay_sqrt * p[i];
            }
        }
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // The crate asks for a Jacobian once per accepted step: one epoch. Stopping here
        // (returning None) also spares the crate the QR factorisation of that Jacobian.
        let p = self.net.to_params();
        let go_on = self
            .stop
            .borrow_mut()
            .check(self.val_err(), &p, self.settings);
        if !go_on {
            return None;
        }
        let n_p = p.len();
        let ld = self.n_res();
        let mut j = DMatrix::zeros(ld, n_p);
        let mut r = vec![0.0; self.xs.nrows() * self.ts.ncols()];
        self.net
            .residuals_and_jacobian(self.xs, self.ts, &mut r, Some((j.as_mut_slice(), ld)));
        if self.decay_sqrt > 0.0 {
            let base = self.xs.nrows() * self.ts.ncols();
            for (row, &i) in self.weight_idx.iter().enumerate() {
                j[(base + row, i)] = self.decay_sqrt;
            }
        }
        Some(j)
    }
}

/// Trains an n-k-2 perceptron on `inputs` -> `targets` (metres) with `settings`,
/// deterministically for `seed`.
pub fn train(
    inputs: &[Vec<f64>],
    targets: &[[f64; 2]],
    settings: &TrainSettings,
    seed: u64,
) -> Result<TrainedNet, TrainError> {
    settings.validate()?;
    let n = inputs.len();
    if n != targets.len() {
        return Err(TrainError::Dataset(format!(
            "{} input rows but {} targets",
            n,
            targets.len()
        )));
    }
    let n_in = inputs.first().map_or(0, |r| r.len());
    if n_in == 0 || inputs.iter().any(|r| r.len() != n_in) {
        return Err(TrainError::Dataset(
            "input rows are empty or of unequal length".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rng);
    let n_val = if settings.val_fraction > 0.0 {
        ((n as f64 * settings.val_fraction).round() as usize).max(1)
    } else {
        0
    };
    if n < n_val + 3 {
        return Err(TrainError::TooFewSamples(format!(
            "{n} training samples; need at least {} (3 to fit plus {n_val} for validation)",
            n_val + 3
        )));
    }
    let (val_idx, fit_idx) = order.split_at(n_val);

    let in_rows: Vec<&[f64]> = inputs.iter().map(|r| r.as_slice()).collect();
    let out_rows: Vec<&[f64]> = targets.iter().map(|t| t.as_slice()).collect();
    let inorm = Normalisation::fit(&in_rows);
    let onorm = output_norm(&out_rows);
    let (xs, ts) = matrices(fit_idx, inputs, targets, &inorm, &onorm);
    let (vx, vt) = matrices(val_idx, inputs, targets, &inorm, &onorm);
    let val = if n_val > 0 { Some((&vx, &vt)) } else { None };

    let mut net = Perceptron::init(n_in, settings.hidden, 2, &mut rng);
    let weight_idx: Vec<usize> = (0..net.n_params()).filter(|&i| net.is_weight(i)).collect();
    let stop = match settings.method {
        Method::Lm => {
            let problem = NetProblem {
                stop: RefCell::new(EarlyStop::new(net.to_params())),
                net: net.clone(),
                xs: &xs,
                ts: &ts,
                val,
                decay_sqrt: settings.weight_decay.sqrt(),
                weight_idx,
                settings,
            };
            let (problem, report) = LevenbergMarquardt::new()
                .with_patience(1000)
                .with_stepbound(LM_STEP_BOUND)
                .with_scale_diag(false)
                .minimize(problem);
            let mut stop = problem.stop.into_inner();
            let p = problem.net.to_params();
            net = problem.net.clone();
            match report.termination {
                TerminationReason::User(_) => {}
                TerminationReason::Numerical(what) => {
                    if stop.best_val == f64::INFINITY && val.is_some() {
                        return Err(TrainError::Numerical(format!("LM failed on {what}")));
                    }
                    stop.reason = Some(format!("LM numerical stop ({what})"));
                }
                other => {
                    // Converged: the last accepted point has not been checked yet.
                    let v = val.map(|(vx, vt)| sse(&problem.net, vx, vt));
                    let mut relaxed = settings.clone();
                    relaxed.max_epochs = usize::MAX;
                    stop.check(v, &p, &relaxed);
                    stop.reason = Some(format!("LM converged: {}", converged_why(&other)));
                }
            }
            stop
        }
        Method::Backprop => {
            let mut p = net.to_params();
            let mut stop = EarlyStop::new(p.clone());
            let mut vel = DVector::zeros(p.len());
            let scale = 1.0 / xs.nrows() as f64;
            loop {
                let v = val.map(|(vx, vt)| sse(&net, vx, vt));
                if !stop.check(v, &p, settings) {
                    break;
                }
                let (_, mut g) = net.error_and_gradient(&xs, &ts);
                g *= scale;
                if settings.weight_decay > 0.0 {
                    for &i in &weight_idx {
                        g[i] += settings.weight_decay * scale * p[i];
                    }
                }
                vel = vel * settings.momentum - g * settings.learning_rate;
                p += &vel;
                if p.iter().any(|v| !v.is_finite()) {
                    return Err(TrainError::Numerical(
                        "back-propagation diverged; lower the learning rate".into(),
                    ));
                }
                net.set_params(&p);
            }
            stop
        }
    };
    net.set_params(&stop.best_params);
    Ok(TrainedNet {
        net,
        input_norm: inorm,
        output_norm: onorm,
        best_epoch: stop.best_epoch,
        epochs_run: stop.epoch,
        stop_reason: stop.reason.unwrap_or_else(|| "stopped".into()),
        n_fit: fit_idx.len(),
        fit_indices: fit_idx.to_vec(),
        validation_indices: val_idx.to_vec(),
        backward: None,
    })
}

/// Input of the feature rule holding x_8, the dead-reckoned forward position at 8/9 of the
/// run: negative for a run driven backwards.
const LAST_X_INPUT: usize = 14;

/// Whether a straight run's inputs (the feature rule's 18) are those of a run driven
/// backwards: its dead-reckoned position near the end lies behind the start.
pub fn drives_backwards(inputs: &[f64]) -> bool {
    inputs.len() == N_INPUTS && inputs[LAST_X_INPUT] < 0.0
}

/// Trains the corrector of straight runs (rows of the feature rule's 18 inputs) as [`train`]
/// does, but with the runs driven backwards on a net of their own when there are runs driven
/// both ways. One net fitting both fits two clusters 3 m apart whose corrections differ
/// (a wheel's error turns a backward run the other way): normalised over both, each
/// cluster's centimetre corrections drown in the spread between them, and early stopping
/// kept a net no better than raw odometry (40 + 40 runs: 6.9 % cross-validated against
/// 4.4 % and 4.6 % for each direction alone). No symmetry maps one direction onto the
/// other for every robot (a mirror in x holds for wheel-size errors, not for a caster or
/// slip that depends on the direction), so each direction learns from its own runs.
pub fn train_runs(
    inputs: &[Vec<f64>],
    targets: &[[f64; 2]],
    settings: &TrainSettings,
    seed: u64,
) -> Result<TrainedNet, TrainError> {
    let (back, fwd): (Vec<usize>, Vec<usize>) =
        (0..inputs.len()).partition(|&i| drives_backwards(&inputs[i]));
    if back.is_empty() || fwd.is_empty() || targets.len() != inputs.len() {
        return train(inputs, targets, settings, seed);
    }
    let one_way = |idx: &[usize], seed: u64, way: &str, other: &[usize]| {
        let i: Vec<Vec<f64>> = idx.iter().map(|&j| inputs[j].clone()).collect();
        let t: Vec<[f64; 2]> = idx.iter().map(|&j| targets[j]).collect();
        train(&i, &t, settings, seed).map_err(|e| match e {
            TrainError::TooFewSamples(m) => TrainError::TooFewSamples(format!(
                "{} runs driven {way} beside {} driven the other way: each direction is corrected by a net of its own, trained on its own runs ({m}); record more runs driven {way}, or leave them out of the manifest",
                idx.len(),
                other.len()
            )),
            other => other,
        })
    };
    let mut net = one_way(&fwd, seed, "forwards", &back)?;
    // Another stream than the forward net's, so that the two nets do not start alike.
    let b = one_way(&back, seed ^ 0xBAC4_0000_0000_0001, "backwards", &fwd)?;
    let to_rows = |idx: &[usize], rows: &[usize]| idx.iter().map(|&j| rows[j]).collect::<Vec<_>>();
    net.fit_indices = to_rows(&net.fit_indices, &fwd);
    net.fit_indices.extend(to_rows(&b.fit_indices, &back));
    net.validation_indices = to_rows(&net.validation_indices, &fwd);
    net.validation_indices
        .extend(to_rows(&b.validation_indices, &back));
    net.n_fit += b.n_fit;
    net.backward = Some(Box::new(b));
    Ok(net)
}
