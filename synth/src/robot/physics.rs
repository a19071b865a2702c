//! The robot's physics, shared by the straight-run protocol and the path driver: motors with
//! a time constant and a disturbance, wheels that slip, a floor that nudges the heading.

use super::*;

/// Uniform draw from [min, max) (the minimum when the range is empty).
pub(super) fn uniform(rng: &mut ChaCha8Rng, r: [f64; 2]) -> f64 {
    if r[1] > r[0] {
        rng.gen_range(r[0]..r[1])
    } else {
        r[0]
    }
}

/// Physical state of the robot.
pub(super) struct Robot {
    pub(super) pose: Pose2,
    /// Wheel angles since the log started, radians.
    pub(super) phi: [f64; 2],
    /// Random initial encoder phase, radians in [0, one count).
    pub(super) phi0: [f64; 2],
    /// Wheel angular speeds, rad/s.
    pub(super) omega: [f64; 2],
    /// Commanded wheel angular speeds, rad/s.
    pub(super) omega_cmd: [f64; 2],
    /// Random slip state (unit-variance OU in distance) per wheel.
    pub(super) slip: [f64; 2],
    /// Motor disturbance state (unit-variance OU in time) per wheel.
    pub(super) motor: [f64; 2],
    /// Body speed of the last step, m/s.
    pub(super) speed: f64,
    /// Ground speed of each wheel in the last step, m/s.
    pub(super) wheel_speed: [f64; 2],
    /// Distance travelled by the wheels' midpoint, metres.
    pub(super) path: f64,
}

impl Robot {
    /// Encoder reading of wheel `w` (counts of `count` radians).
    pub(super) fn ticks(&self, w: usize, count: f64) -> i64 {
        ((self.phi[w] + self.phi0[w]) / count).floor() as i64
    }

    /// One physics step of `cfg.sim_dt_s`: motors approach their commands with time constant
    /// `tau_s`, each wheel slips by its speed-dependent fraction at `slip_speed_mps` plus its
    /// random wander, and the floor's roughness turns the body.
    pub(super) fn physics_step(
        &mut self,
        cfg: &RobotSimConfig,
        tau_s: f64,
        slip_speed_mps: [f64; 2],
        rng: &mut ChaCha8Rng,
    ) {
        let dt = cfg.sim_dt_s;
        let sys = &cfg.systematic;
        let rnd = &cfg.random;
        let r_true = [
            0.5 * sys.left_wheel_diameter_m,
            0.5 * sys.right_wheel_diameter_m,
        ];
        let k_slip = [sys.left_slip_per_mps, sys.right_slip_per_mps];
        let gain = [cfg.control.left_motor_gain, cfg.control.right_motor_gain];
        let a_m = (-dt / rnd.motor_noise_time_s).exp();
        let mut ds = [0.0; 2];
        for w in 0..2 {
            let n: f64 = rng.sample(StandardNormal);
            self.motor[w] = a_m * self.motor[w] + (1.0 - a_m * a_m).sqrt() * n;
            let target = gain[w] * self.omega_cmd[w] * (1.0 + rnd.motor_noise_sd * self.motor[w]);
            self.omega[w] += (target - self.omega[w]) * (dt / tau_s).min(1.0);
            self.phi[w] += self.omega[w] * dt;
            let slip = k_slip[w] * slip_speed_mps[w] + rnd.slip_sd * self.slip[w];
            ds[w] = self.omega[w] * r_true[w] * (1.0 - slip) * dt;
        }
        let d = 0.5 * (ds[0] + ds[1]);
        let n: f64 = rng.sample(StandardNormal);
        let d_rot =
            (ds[1] - ds[0]) / sys.wheel_base_m + rnd.roughness_rad_per_sqrt_m * d.abs().sqrt() * n;
        let mid = self.pose.theta_rad + 0.5 * d_rot;
        self.pose = Pose2::new(
            self.pose.x_m + d * mid.cos(),
            self.pose.y_m + d * mid.sin(),
            self.pose.theta_rad + d_rot,
        );
        self.speed = d / dt;
        self.wheel_speed = [ds[0] / dt, ds[1] / dt];
        self.path += d.abs();
        let a_s = (-d.abs() / rnd.slip_correlation_m).exp();
        for w in 0..2 {
            let n: f64 = rng.sample(StandardNormal);
            self.slip[w] = a_s * self.slip[w] + (1.0 - a_s * a_s).sqrt() * n;
        }
    }
}
