//! What a model was trained on, so that it is never applied far outside it: the range of
//! every input, of the path length and speed, and the direction of travel. A corrector fitted
//! to 1.5 m forward runs has no answer for a 15 m run or a run driven backwards; it would
//! return a plausible-looking number, so such logs are refused (or, on request, flagged).

use odocal_dataset::{RobotParams, Sample};
use serde::{Deserialize, Serialize};

/// The share of each input's training range by which it may lie outside it (runs like the
/// training runs but not among them still fit).
pub const INPUT_MARGIN: f64 = 0.25;
/// The share of the longest training run by which a run may be shorter or longer.
pub const LENGTH_MARGIN: f64 = 0.1;

/// The training domain recorded in model.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingDomain {
    /// Smallest and largest value of each of the 18 inputs.
    pub input_min: Vec<f64>,
    /// Largest value of each input.
    pub input_max: Vec<f64>,
    /// Shortest and longest distance from start to raw odometry end, metres.
    pub end_distance_m: [f64; 2],
    /// Whether every training run ended ahead of its start (raw odometry x > 0).
    pub forward_only: bool,
    /// Shortest and longest run, seconds from its start to its end (t_e − t_b): a run at a
    /// speed the training never drove lies within every input's own range (its t_e among the
    /// training's, after a longer wait at rest) and only its duration shows it. Absent from
    /// models trained before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<[f64; 2]>,
}

/// A run's duration from the feature rule's t_b and t_e (its last two inputs), seconds.
fn duration_s(inputs: &[f64]) -> Option<f64> {
    match inputs {
        [.., t_b, t_e] if inputs.len() == odocal_dataset::N_INPUTS => Some(t_e - t_b),
        _ => None,
    }
}

impl TrainingDomain {
    /// The domain of a set of samples (None when there are none).
    pub fn of(samples: &[Sample]) -> Option<Self> {
        let first = samples.first()?;
        let n = first.inputs.len();
        let (mut lo, mut hi) = (vec![f64::INFINITY; n], vec![f64::NEG_INFINITY; n]);
        let mut path = [f64::INFINITY, f64::NEG_INFINITY];
        for s in samples {
            for (i, &v) in s.inputs.iter().enumerate().take(n) {
                lo[i] = lo[i].min(v);
                hi[i] = hi[i].max(v);
            }
            let d = s.raw_end_m[0].hypot(s.raw_end_m[1]);
            path = [path[0].min(d), path[1].max(d)];
        }
        let durations: Option<Vec<f64>> = samples.iter().map(|s| duration_s(&s.inputs)).collect();
        let duration_s = durations.map(|d| {
            d.iter()
                .fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], &v| {
                    [a.min(v), b.max(v)]
                })
        });
        Some(Self {
            input_min: lo,
            input_max: hi,
            end_distance_m: path,
            forward_only: samples.iter().all(|s| s.raw_end_m[0] > 0.0),
            duration_s,
        })
    }

    /// Why a log with these inputs and raw end point lies outside the domain (each reason
    /// with its figures), or an empty list when it lies inside.
    pub fn outside(&self, inputs: &[f64], raw_end_m: [f64; 2]) -> Vec<String> {
        let mut why = Vec::new();
        let [p0, p1] = self.end_distance_m;
        let pm = LENGTH_MARGIN * p1 + INPUT_MARGIN * (p1 - p0);
        let d = raw_end_m[0].hypot(raw_end_m[1]);
        if !(d >= p0 - pm && d <= p1 + pm) {
            why.push(format!(
                "it ends {d:.3} m from its start (trained on {p0:.3} to {p1:.3} m)"
            ));
        }
        if let (Some([a, b]), Some(t)) = (self.duration_s, duration_s(inputs)) {
            let m = INPUT_MARGIN * (b - a).max(0.1 * b);
            if !(t >= a - m && t <= b + m) {
                why.push(format!(
                    "it takes {t:.2} s from its start to its end (t_e − t_b; trained on {a:.2} to {b:.2} s): a speed the training did not drive"
                ));
            }
        }
        if self.forward_only && raw_end_m[0] <= 0.0 {
            why.push(format!(
                "the run ends {:.3} m behind its start (trained on forward runs only)",
                -raw_end_m[0]
            ));
        }
        for (i, &v) in inputs.iter().enumerate() {
            let (Some(&a), Some(&b)) = (self.input_min.get(i), self.input_max.get(i)) else {
                continue;
            };
            let m = INPUT_MARGIN * (b - a).abs().max(1e-3);
            if !(v >= a - m && v <= b + m) {
                // The 18 inputs of the feature rule: x_k, y_k of the dead-reckoned run at eight
                // times, then t_b and t_e on the robot's clock.
                let what = match i {
                    // The source's rule reads the run's times themselves: a robot that waits
                    // longer at rest before the run (identical motion, 2 s later) is outside
                    // the training, and was blamed on the log's clock.
                    16 => format!(" (t_b, the run's start on the robot's clock: it starts moving at {v:.2} s, after its wait at rest, where the training runs started at {a:.2} to {b:.2} s; the net reads this time itself, so a longer or shorter wait at rest before the run, or a clock that does not count from the log's start as the training's did, is outside what it learned: start the log about as long before the run as the training logs were)"),
                    17 => " (t_e, the run's end on the robot's clock, s: it moves with the wait at rest before the run, t_b, and with the run's duration)".to_string(),
                    _ if i < 16 => format!(
                        " ({}_{}, the dead-reckoned {} at {}/9 of the run, m)",
                        if i % 2 == 0 { "x" } else { "y" },
                        i / 2 + 1,
                        if i % 2 == 0 { "forward position" } else { "sideways position" },
                        i / 2 + 1
                    ),
                    _ => String::new(),
                };
                why.push(format!(
                    "input {i} = {v:.4}{what} (trained on {a:.4} to {b:.4})"
                ));
                break;
            }
        }
        why
    }
}

/// A wheel whose travel over one log step is below this counts as standing still, metres:
/// tick logs give exact zeros, velocity logs a little noise at rest (0.1 mm per step is
/// 0.5 mm/s at 200 ms, far below any driving speed).
const STILL_TRAVEL_M: f64 = 1e-4;

/// A direction of wheel motion is untrained when fewer than this share of the training's
/// moving steps went that way: tours drive backwards in about 0.4 % of their steps (a wheel
/// settling after a turn on the spot), a log driven backwards in over 80 %.
pub const UNTRAINED_DIRECTION_SHARE: f64 = 0.02;

/// A log lies outside the domain when more than this share of its moving steps go in an
/// untrained direction; a few such steps (settling, a nudge) are within the model's reach.
pub const LOG_DIRECTION_SHARE: f64 = 0.05;

/// Which ways the wheels turned over the moving steps of a set of logs: the share of steps
/// per sign pattern of the two wheels' travels. The path corrector maps a step's wheel
/// speeds to corrections; for a quadrant of (left, right) it never saw, such as both wheels
/// backwards after training on forward tours, its output is an extrapolation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct StepDirections {
    /// Steps in which at least one wheel turned.
    pub moving_steps: usize,
    /// Share of them with both wheels forwards.
    pub both_forward: f64,
    /// Share with both wheels backwards: driving backwards.
    pub both_backward: f64,
    /// Share with the left wheel backwards and the right forwards: turning counter-clockwise
    /// on the spot.
    pub spin_counter_clockwise: f64,
    /// Share with the left wheel forwards and the right backwards: turning clockwise on the
    /// spot.
    pub spin_clockwise: f64,
    /// Share with one wheel still (a pivot, or one encoder's count not yet changed).
    pub one_wheel_still: f64,
}

/// The four sign patterns with both wheels turning, in the order of
/// [`StepDirections::patterns`]: what a model not trained on it lacks, and what a log does.
const PATTERNS: [(&str, &str); 4] = [
    ("driving forwards", "drives forwards (both wheels forwards)"),
    (
        "driving backwards",
        "drives backwards (both wheels backwards)",
    ),
    (
        "turning counter-clockwise on the spot",
        "turns counter-clockwise on the spot (left wheel backwards, right forwards)",
    ),
    (
        "turning clockwise on the spot",
        "turns clockwise on the spot (left wheel forwards, right backwards)",
    ),
];

impl StepDirections {
    /// The directions of steps given as nominal wheel travels [left, right], metres.
    pub fn of_steps(steps: impl IntoIterator<Item = [f64; 2]>) -> Self {
        let mut count = [0usize; 5];
        for d in steps {
            let sign = |v: f64| {
                if v > STILL_TRAVEL_M {
                    1
                } else if v < -STILL_TRAVEL_M {
                    -1
                } else {
                    0
                }
            };
            let slot = match (sign(d[0]), sign(d[1])) {
                (0, 0) => continue,
                (1, 1) => 0,
                (-1, -1) => 1,
                (-1, 1) => 2,
                (1, -1) => 3,
                _ => 4,
            };
            count[slot] += 1;
        }
        let n: usize = count.iter().sum();
        let share = |c: usize| if n == 0 { 0.0 } else { c as f64 / n as f64 };
        Self {
            moving_steps: n,
            both_forward: share(count[0]),
            both_backward: share(count[1]),
            spin_counter_clockwise: share(count[2]),
            spin_clockwise: share(count[3]),
            one_wheel_still: share(count[4]),
        }
    }

    fn patterns(&self) -> [f64; 4] {
        [
            self.both_forward,
            self.both_backward,
            self.spin_counter_clockwise,
            self.spin_clockwise,
        ]
    }

    /// Checks that every share is a number in [0, 1] and that they add up to 1 (a file's
    /// field, so read back from a hand-edited file); the message names the first that is not.
    pub fn check(&self) -> Result<(), String> {
        let shares = [
            ("both_forward", self.both_forward),
            ("both_backward", self.both_backward),
            ("spin_counter_clockwise", self.spin_counter_clockwise),
            ("spin_clockwise", self.spin_clockwise),
            ("one_wheel_still", self.one_wheel_still),
        ];
        for (name, v) in shares {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{name} = {v} must be a share in [0, 1]"));
            }
        }
        let sum: f64 = shares.iter().map(|(_, v)| v).sum();
        if self.moving_steps > 0 && (sum - 1.0).abs() > 1e-6 {
            return Err(format!(
                "the shares add up to {sum:.4}, not 1 (each is a share of the moving steps)"
            ));
        }
        Ok(())
    }

    /// Why a log whose steps go in `log`'s directions lies outside a training that went in
    /// these (one reason per untrained direction the log takes), or an empty list.
    pub fn outside(&self, log: &StepDirections) -> Vec<String> {
        let mut why = Vec::new();
        for (i, (trained, seen)) in self.patterns().into_iter().zip(log.patterns()).enumerate() {
            if trained >= UNTRAINED_DIRECTION_SHARE || seen <= LOG_DIRECTION_SHARE {
                continue;
            }
            let steps = (seen * log.moving_steps as f64).round() as usize;
            let (lacks, does) = PATTERNS[i];
            // Driving backwards is the case users meet (a reversing robot, or a log's sign
            // convention flipped), so it is named by what the model did learn.
            let trained_on = if i == 1 {
                "the model was trained on forward driving".to_string()
            } else {
                format!("the model was not trained on {lacks}")
            };
            why.push(format!(
                "{trained_on} ({lacks} in {:.1} % of its moving training steps), but the log {does} in {:.1} % of its moving steps ({steps} of {})",
                100.0 * trained,
                100.0 * seen,
                log.moving_steps
            ));
        }
        why
    }
}

/// Refuses to apply a model trained for robot `model` to data of robot `given` (`whose`
/// names the data: a log, a manifest). The message lists each parameter that differs, with
/// both values and their units: a model learns one robot's kinematics, and its corrections
/// are relative to that robot's nominal geometry and logging period.
pub fn check_same_robot(
    model: &RobotParams,
    given: &RobotParams,
    whose: &str,
) -> Result<(), crate::TrainError> {
    // A robot file written by hand or by another program carries the same values to a few
    // digits (0.0430000001 for 0.043 was refused); no robot differs by a millionth.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(1e-12);
    let params = [
        (
            "wheel diameter",
            model.wheel_diameter_m,
            given.wheel_diameter_m,
            1e3,
            " mm",
            3,
        ),
        (
            "wheel base",
            model.wheel_base_m,
            given.wheel_base_m,
            1e3,
            " mm",
            2,
        ),
        (
            "encoder counts per revolution",
            model.ticks_per_rev,
            given.ticks_per_rev,
            1.0,
            "",
            0,
        ),
        (
            "logging period",
            model.period_s,
            given.period_s,
            1.0,
            " s",
            3,
        ),
    ];
    let differ: Vec<String> = params
        .iter()
        .filter(|(_, m, g, ..)| !close(*m, *g))
        .map(|(name, m, g, scale, unit, digits)| {
            let (m, g) = (m * scale, g * scale);
            // Values that differ are printed so that they do (12.5 is not "12").
            let mut d = *digits;
            while d < 9 && format!("{m:.d$}") == format!("{g:.d$}") {
                d += 1;
            }
            format!("{name} {m:.d$}{unit} in the model vs {g:.d$}{unit} given")
        })
        .collect();
    if differ.is_empty() {
        return Ok(());
    }
    Err(crate::TrainError::Model(format!(
        "the model was trained for another robot than the one given for {whose}: {}; pass the robot the model was trained for (or leave out --robot), or train a model on this robot's data",
        differ.join(", ")
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run whose robot waited 2 s longer at rest before it, its motion the same: the net
    /// reads t_b itself, so it is outside, and the refusal names the wait at rest (it asked
    /// whether the log's clock started where the training logs' did).
    #[test]
    fn a_longer_wait_at_rest_is_named_as_such() {
        let text = include_str!("../../tests/data/parsers/dataset.json");
        let ds = odocal_dataset::Dataset::parse(text, "dataset.json").expect("parses");
        let domain = TrainingDomain::of(&ds.samples).expect("a domain");
        let mut later = ds.samples[0].inputs.clone();
        let (lo, hi) = (domain.input_min[16], domain.input_max[16]);
        later[16] = hi + 2.0;
        later[17] += hi + 2.0 - ds.samples[0].inputs[16];
        let why = domain.outside(&later, ds.samples[0].raw_end_m);
        let t_b = why
            .iter()
            .find(|w| w.starts_with("input 16 = "))
            .expect("t_b named");
        assert!(
            t_b.contains(&format!(
                "it starts moving at {:.2} s, after its wait at rest, where the training runs started at {lo:.2} to {hi:.2} s"
            , hi + 2.0)) && !t_b.contains("does this log's clock start"),
            "{t_b}"
        );
    }

    /// A run at a speed the training never drove, its every input within the training's
    /// range with its margin (its t_e among theirs after a longer wait at rest), was
    /// corrected without a word: its duration names it.
    #[test]
    fn a_run_of_an_untrained_duration_is_outside() {
        let text = include_str!("../../tests/data/parsers/dataset.json");
        let ds = odocal_dataset::Dataset::parse(text, "dataset.json").expect("parses");
        // Runs of 3.6 to 4.2 s, started 0.8 to 1.4 s into their logs.
        let trained: Vec<Sample> = ds.samples[1..4]
            .iter()
            .cloned()
            .zip([3.9, 4.2, 3.6])
            .map(|(mut s, d)| {
                s.inputs[17] = s.inputs[16] + d;
                s
            })
            .collect();
        let domain = TrainingDomain::of(&trained).expect("a domain");
        assert_eq!(
            domain.duration_s.map(|d| d.map(|v| (v * 10.0).round())),
            Some([36.0, 42.0])
        );
        let run = &trained[1];
        assert!(domain.outside(&run.inputs, run.raw_end_m).is_empty());
        // Started 1.4 s in and ended at 4.2 s: both times among the training's.
        let mut fast = run.inputs.clone();
        fast[17] = fast[16] + 2.8;
        let why = domain.outside(&fast, run.raw_end_m);
        assert!(
            why.len() == 1 && why[0].contains("it takes 2.80 s from its start to its end"),
            "{why:?}"
        );
    }

    /// Steps of a forward tour: mostly both wheels forwards, some turns on the spot both
    /// ways, a wheel settling backwards now and then, and rests.
    fn tour() -> Vec<[f64; 2]> {
        let mut steps = Vec::new();
        for i in 0..100 {
            steps.push(match i % 20 {
                0 => [0.0, 0.0],
                1 => [-0.01, 0.01],
                2 => [0.01, -0.01],
                _ => [0.05, 0.06],
            });
        }
        steps.push([-0.01, -0.01]);
        steps
    }

    #[test]
    fn a_log_driven_backwards_is_outside_a_forward_training_with_its_share() {
        let trained = StepDirections::of_steps(tour());
        assert_eq!(trained.moving_steps, 96);
        assert!((trained.both_backward - 1.0 / 96.0).abs() < 1e-12);
        assert!(trained.check().is_ok());
        assert!(trained
            .outside(&StepDirections::of_steps(tour()))
            .is_empty());
        let back: Vec<[f64; 2]> = tour().iter().map(|d| [-d[0], -d[1]]).collect();
        let why = trained.outside(&StepDirections::of_steps(back));
        assert_eq!(why.len(), 1, "{why:?}");
        assert!(
            why[0].starts_with("the model was trained on forward driving (driving backwards in 1.0 % of its moving training steps), but the log drives backwards (both wheels backwards) in 88.5 % of its moving steps (85 of 96)"),
            "{}",
            why[0]
        );
    }

    #[test]
    fn a_few_backward_steps_and_velocity_noise_at_rest_stay_inside() {
        let trained = StepDirections::of_steps(tour());
        // 4 % of the steps backwards: a nudge, not reversing.
        let mut log: Vec<[f64; 2]> = vec![[0.05, 0.05]; 96];
        log.extend([[-0.02, -0.02]; 4]);
        // A velocity log's noise at rest is no motion in any direction.
        log.extend([[-3e-5, -2e-5]; 500]);
        assert!(trained.outside(&StepDirections::of_steps(log)).is_empty());
    }

    #[test]
    fn turning_on_the_spot_one_way_only_is_outside_a_training_without_it() {
        let trained = StepDirections::of_steps(vec![[0.05, 0.05]; 50]);
        let why = trained.outside(&StepDirections::of_steps(tour()));
        assert_eq!(why.len(), 2, "{why:?}");
        assert!(
            why[0].starts_with("the model was not trained on turning counter-clockwise on the spot (turning counter-clockwise on the spot in 0.0 % of its moving training steps), but the log turns counter-clockwise on the spot (left wheel backwards, right forwards) in 5.2 %"),
            "{}",
            why[0]
        );
    }

    #[test]
    fn shares_that_are_no_shares_are_refused() {
        let mut d = StepDirections::of_steps(tour());
        d.both_forward = 1.5;
        assert_eq!(
            d.check().unwrap_err(),
            "both_forward = 1.5 must be a share in [0, 1]"
        );
        let mut d = StepDirections::of_steps(tour());
        d.both_forward -= 0.5;
        assert!(d.check().unwrap_err().contains("add up to 0.5000"));
    }

    #[test]
    fn another_robot_is_named_by_the_parameters_that_differ_with_units() {
        let robot = RobotParams::default();
        assert!(check_same_robot(&robot, &robot, "run.csv").is_ok());
        let written_elsewhere = RobotParams {
            wheel_diameter_m: 0.0430000001,
            wheel_base_m: 0.1 * (1.0 + 9e-7),
            ..robot
        };
        assert!(check_same_robot(&robot, &written_elsewhere, "run.csv").is_ok());
        let a_micron_in_a_metre_more = RobotParams {
            wheel_base_m: 0.1 * (1.0 + 2e-6),
            ..robot
        };
        assert!(check_same_robot(&robot, &a_micron_in_a_metre_more, "run.csv").is_err());
        let other = RobotParams {
            wheel_diameter_m: 0.045,
            period_s: 0.1,
            ..robot
        };
        let e = check_same_robot(&robot, &other, "run.csv")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "model: the model was trained for another robot than the one given for run.csv: wheel diameter 43.000 mm in the model vs 45.000 mm given, logging period 0.200 s in the model vs 0.100 s given; pass the robot the model was trained for (or leave out --robot), or train a model on this robot's data"
        );
        assert!(!e.contains("RobotParams"));
    }
}
