//! A small stand-in robot simulator for the trainer's tests: straight runs of a
//! differential-drive robot with unequal wheels, a wrong wheel base, speed-dependent
//! slip, random slip, heading oscillation and 12-count encoders, logged every 200 ms.
//! Features come from the dataset crate's own feature builder (the exact rule).

#![allow(dead_code)]

use std::collections::HashMap;

use odocal_dataset::{features_from_log, Dataset, OdometryLog, RobotParams, Sample, WheelGeometry};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// True systematic parameters of the simulated robot.
#[derive(Debug, Clone, Copy)]
pub struct Truth {
    /// Left wheel radius multiplier.
    pub c_l: f64,
    /// Right wheel radius multiplier.
    pub c_r: f64,
    /// Wheel base multiplier.
    pub c_b: f64,
    /// Effective radius loss per m/s of speed (systematic slip).
    pub slip_per_mps: f64,
}

impl Default for Truth {
    fn default() -> Self {
        Self {
            c_l: 0.995,
            c_r: 1.005,
            c_b: 1.05,
            slip_per_mps: 0.03,
        }
    }
}

/// A simulated experiment: the dataset plus the oracle end points by run id.
pub struct Experiment {
    pub dataset: Dataset,
    pub oracle: HashMap<String, [f64; 2]>,
    pub logs: Vec<(String, String)>,
}

/// Simulates `n_runs` straight runs of 1.5 m at 0.2, 0.5 and 0.7 m/s.
pub fn experiment(n_runs: usize, seed: u64, truth: Truth) -> Experiment {
    let robot = RobotParams::default();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let speeds = [0.2, 0.5, 0.7];
    let mut samples = Vec::new();
    let mut oracle = HashMap::new();
    let mut logs = Vec::new();
    for i in 0..n_runs {
        let v = speeds[i % 3];
        let id = format!("run{i:03}");
        let (log_csv, s, o) = run(&id, v, &robot, &truth, &mut rng);
        oracle.insert(id.clone(), o);
        samples.push(s);
        logs.push((id, log_csv));
    }
    Experiment {
        dataset: Dataset::new(robot, samples, Vec::new(), n_runs),
        oracle,
        logs,
    }
}

fn run(
    id: &str,
    v: f64,
    robot: &RobotParams,
    tr: &Truth,
    rng: &mut ChaCha8Rng,
) -> (String, Sample, [f64; 2]) {
    let dt = 0.01;
    let r_nom = robot.wheel_diameter_m / 2.0;
    let b_true = robot.wheel_base_m * tr.c_b;
    let rad_per_tick = 2.0 * std::f64::consts::PI / robot.ticks_per_rev;
    let slip = 1.0 - tr.slip_per_mps * v;
    let noise = Normal::new(0.0, 0.03).unwrap_or_else(|_| unreachable!());
    let osc_amp = 0.12;
    let osc_hz = rng.gen_range(0.6..1.2);
    let osc_phase = rng.gen_range(0.0..std::f64::consts::TAU);
    // Floor roughness: a random curvature of the run.
    let bias = Normal::new(0.0, 0.01)
        .unwrap_or_else(|_| unreachable!())
        .sample(rng);
    let t_start = rng.gen_range(0.5..1.0);
    let dist: f64 = 1.5;
    let ramp: f64 = 0.3;
    let (mut phi_l, mut phi_r) = (0.0f64, 0.0f64);
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    let mut path = 0.0;
    let mut t = 0.0;
    let mut rows = vec![(0.0, 0i64, 0i64)];
    let mut next_log = robot.period_s;
    let mut stopped_at: Option<f64> = None;
    while t < 30.0 {
        t += dt;
        let moving = t > t_start && stopped_at.is_none();
        if moving {
            let odo_dist = 0.5 * (phi_l + phi_r) * r_nom;
            let ramp_f = ((t - t_start) / ramp)
                .min(1.0)
                .min(((dist - odo_dist) / (v * ramp)).max(0.05));
            let w = v * ramp_f / r_nom;
            let osc = osc_amp * (std::f64::consts::TAU * osc_hz * t + osc_phase).sin();
            let dl = w * (1.0 - osc) * dt;
            let dr = w * (1.0 + osc) * dt;
            phi_l += dl;
            phi_r += dr;
            let l = dl * r_nom * tr.c_l * slip * (1.0 + noise.sample(rng));
            let r = dr * r_nom * tr.c_r * slip * (1.0 + noise.sample(rng));
            let tr_ = 0.5 * (l + r);
            let rot = (r - l) / b_true + bias * tr_;
            x += tr_ * (th + rot / 2.0).cos();
            y += tr_ * (th + rot / 2.0).sin();
            th += rot;
            path += tr_.abs();
            if odo_dist >= dist {
                stopped_at = Some(t);
            }
        }
        if t + 1e-9 >= next_log {
            let lt = (phi_l / rad_per_tick).floor() as i64;
            let rt = (phi_r / rad_per_tick).floor() as i64;
            rows.push((next_log, lt, rt));
            next_log += robot.period_s;
            if let Some(ts) = stopped_at {
                if t > ts + 1.0 {
                    break;
                }
            }
        }
    }
    let mut csv = String::from("t,left_ticks,right_ticks\n");
    for (t, l, r) in &rows {
        csv.push_str(&format!("{t:.3},{l},{r}\n"));
    }
    let log = OdometryLog::from_ticks(
        rows.iter().map(|r| r.0).collect(),
        rows.iter().map(|r| r.1).collect(),
        rows.iter().map(|r| r.2).collect(),
    )
    .unwrap_or_else(|e| panic!("stand-in log invalid: {e}"));
    let f = features_from_log(&log, robot).unwrap_or_else(|e| panic!("features: {e}"));
    let geom = WheelGeometry {
        left_wheel_diameter_m: robot.wheel_diameter_m * tr.c_l * slip,
        right_wheel_diameter_m: robot.wheel_diameter_m * tr.c_r * slip,
        wheel_base_m: b_true,
    };
    let oracle = f.odometry.end_m(&geom);
    let sample = Sample {
        run_id: id.to_string(),
        speed_mps: v,
        inputs: f.inputs.to_vec(),
        target_m: [x, y],
        raw_end_m: f.raw_end_m,
        path_length_m: path,
        recording_id: id.to_string(),
        odometry: f.odometry,
        ..Default::default()
    };
    (csv, sample, oracle)
}
