//! The simulator's configuration: the nominal robot, its systematic and random errors, the
//! controller, the experiment protocol and the camera timing, each checked for physical sense.

use super::*;
use odocal_dataset::odometry::MAX_WHEEL_SPEED_MPS;

/// The `format` tag of simulator configuration files.
pub const ROBOT_SIM_FORMAT: &str = "odocal.robotsim/1";

/// Why a simulator configuration is unusable.
#[derive(Debug, Error)]
pub enum RobotSimError {
    /// The file could not be read or is not a simulator config (names the file).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// A parameter is out of its range.
    #[error("robot simulator config: {0}")]
    Invalid(String),
}

/// The robot as its odometry believes it to be.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NominalRobot {
    /// Nominal wheel diameter, metres.
    pub wheel_diameter_m: f64,
    /// Encoder counts per wheel revolution.
    pub ticks_per_rev: u32,
    /// Nominal wheel base, metres.
    pub wheel_base_m: f64,
    /// Odometry logging period, seconds.
    pub log_period_s: f64,
}

impl Default for NominalRobot {
    fn default() -> Self {
        Self {
            wheel_diameter_m: 0.043,
            ticks_per_rev: 12,
            wheel_base_m: 0.10,
            log_period_s: 0.2,
        }
    }
}

/// The systematic error: the robot's true geometry and speed-dependent slip.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SystematicError {
    /// True left wheel diameter, metres.
    pub left_wheel_diameter_m: f64,
    /// True right wheel diameter, metres.
    pub right_wheel_diameter_m: f64,
    /// True effective wheel base, metres.
    pub wheel_base_m: f64,
    /// Left wheel slip fraction per m/s of body speed, s/m.
    pub left_slip_per_mps: f64,
    /// Right wheel slip fraction per m/s of body speed, s/m.
    pub right_slip_per_mps: f64,
}

impl Default for SystematicError {
    fn default() -> Self {
        Self {
            left_wheel_diameter_m: 0.04205,
            right_wheel_diameter_m: 0.04265,
            wheel_base_m: 0.104,
            left_slip_per_mps: 0.030,
            right_slip_per_mps: 0.036,
        }
    }
}

/// The random error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomError {
    /// Standard deviation of each wheel's random slip fraction.
    pub slip_sd: f64,
    /// Correlation length of the random slip along the path, metres.
    pub slip_correlation_m: f64,
    /// Floor roughness: heading random walk, radians per square-root metre.
    pub roughness_rad_per_sqrt_m: f64,
    /// Relative motor speed disturbance (seen by the encoders), standard deviation.
    pub motor_noise_sd: f64,
    /// Correlation time of the motor disturbance, seconds.
    pub motor_noise_time_s: f64,
}

impl Default for RandomError {
    fn default() -> Self {
        Self {
            slip_sd: 0.003,
            slip_correlation_m: 0.3,
            roughness_rad_per_sqrt_m: 0.01,
            motor_noise_sd: 0.03,
            motor_noise_time_s: 0.1,
        }
    }
}

/// Motors and the one-wheel PID controller.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Control {
    /// Controller period, seconds.
    pub control_period_s: f64,
    /// Acceleration of the speed set-point ramp, m/s².
    pub accel_mps2: f64,
    /// Motor time constant while driving, seconds.
    pub motor_time_constant_s: f64,
    /// Motor time constant while braking, seconds.
    pub brake_time_constant_s: f64,
    /// Left motor gain (true speed / commanded speed).
    pub left_motor_gain: f64,
    /// Right motor gain (true speed / commanded speed).
    pub right_motor_gain: f64,
    /// Slave-wheel PID: proportional gain, rad/s per count of difference.
    pub kp_rad_s_per_tick: f64,
    /// Slave-wheel PID: integral gain, rad/s per count-second.
    pub ki_rad_s_per_tick_s: f64,
    /// Slave-wheel PID: derivative gain, rad/s per count/s.
    pub kd_rad_per_tick: f64,
}

impl Default for Control {
    fn default() -> Self {
        Self {
            control_period_s: 0.01,
            accel_mps2: 1.0,
            motor_time_constant_s: 0.05,
            brake_time_constant_s: 0.03,
            left_motor_gain: 0.97,
            right_motor_gain: 1.03,
            kp_rad_s_per_tick: 3.0,
            ki_rad_s_per_tick_s: 2.0,
            kd_rad_per_tick: 0.05,
        }
    }
}

/// The experimental protocol: runs, pauses and start placement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Protocol {
    /// Run length the robot is told to drive (counted on its master encoder), metres.
    pub run_distance_m: f64,
    /// Commanded speeds, cycled over the runs, m/s.
    pub speeds_mps: Vec<f64>,
    /// Rest after the log starts before the first motion, seconds [min, max].
    pub pre_roll_s: [f64; 2],
    /// Rest after the last run before the log ends, seconds [min, max].
    pub post_roll_s: [f64; 2],
    /// Rest after a run before the robot is carried back (several runs per recording), [min, max] s.
    pub pause_s: [f64; 2],
    /// Time the robot is carried back (tag not visible), [min, max] s.
    pub carry_s: [f64; 2],
    /// Start x position, floor frame, metres.
    pub start_x_m: f64,
    /// Uniform jitter of the start x position, ± metres.
    pub start_x_jitter_m: f64,
    /// Centre of the start y positions, floor frame, metres. The robot's systematic error
    /// curves its runs to the left (+y) by up to 0.3 m, so starts sit right of the centre
    /// line, as a lab would place them to keep the whole run in the camera's view.
    pub start_y_m: f64,
    /// Uniform range of the start y position around `start_y_m`, ± metres.
    pub start_y_range_m: f64,
    /// Standard deviation of the start heading about +x, radians.
    pub start_heading_sd_rad: f64,
}

impl Default for Protocol {
    fn default() -> Self {
        Self {
            run_distance_m: 1.5,
            speeds_mps: vec![0.2, 0.5, 0.7],
            pre_roll_s: [0.6, 1.4],
            post_roll_s: [1.0, 1.6],
            pause_s: [1.0, 1.5],
            carry_s: [1.5, 2.5],
            start_x_m: -0.75,
            start_x_jitter_m: 0.05,
            start_y_m: -0.15,
            start_y_range_m: 0.2,
            start_heading_sd_rad: 0.05,
        }
    }
}

/// The ceiling camera's timing and, for `--frames none`, its measurement noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraTiming {
    /// Frame rate, frames per second.
    pub fps: f64,
    /// The camera starts this long before the robot's log (= the clock offset), [min, max] s.
    pub lead_s: [f64; 2],
    /// The camera stops this long after the robot's log, [min, max] s.
    pub tail_s: [f64; 2],
    /// Position noise of a trajectory from truth (`--frames none`), metres (standard deviation).
    pub position_noise_m: f64,
    /// Heading noise of a trajectory from truth (`--frames none`), radians (standard deviation).
    pub heading_noise_rad: f64,
}

impl Default for CameraTiming {
    fn default() -> Self {
        Self {
            fps: 30.0,
            lead_s: [0.3, 2.0],
            tail_s: [0.3, 1.0],
            position_noise_m: 0.0005,
            heading_noise_rad: 0.002,
        }
    }
}

/// Every parameter of the robot simulator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotSimConfig {
    /// Always [`ROBOT_SIM_FORMAT`].
    pub format: String,
    /// What odometry assumes.
    pub nominal: NominalRobot,
    /// Systematic error.
    pub systematic: SystematicError,
    /// Random error.
    pub random: RandomError,
    /// Motors and controller.
    pub control: Control,
    /// Runs and pauses.
    pub protocol: Protocol,
    /// Camera timing and trajectory noise.
    pub camera: CameraTiming,
    /// Physics time step, seconds (must divide the control and log periods).
    pub sim_dt_s: f64,
}

impl Default for RobotSimConfig {
    fn default() -> Self {
        Self {
            format: ROBOT_SIM_FORMAT.to_string(),
            nominal: NominalRobot::default(),
            systematic: SystematicError::default(),
            random: RandomError::default(),
            control: Control::default(),
            protocol: Protocol::default(),
            camera: CameraTiming::default(),
            sim_dt_s: 0.001,
        }
    }
}

fn ratio_ok(a: f64, dt: f64) -> bool {
    let r = a / dt;
    r >= 1.0 && (r - r.round()).abs() < 1e-6
}

impl RobotSimConfig {
    /// Reads and validates a simulator config file (`"format": "odocal.robotsim/1"`).
    pub fn read(path: &std::path::Path) -> Result<Self, RobotSimError> {
        let cfg: RobotSimConfig = odocal_core::read_tagged_json(
            path,
            ROBOT_SIM_FORMAT,
            "pass a simulator config for `odocal synth experiment --config` (its truth/simulator.json is one)",
        )?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks formats and ranges.
    pub fn validate(&self) -> Result<(), RobotSimError> {
        let bad = |m: &str| Err(RobotSimError::Invalid(m.to_string()));
        if self.format != ROBOT_SIM_FORMAT {
            return bad(&format!(
                "format is \"{}\", expected \"{ROBOT_SIM_FORMAT}\"",
                self.format
            ));
        }
        let pos = [
            self.nominal.wheel_diameter_m,
            self.nominal.wheel_base_m,
            self.nominal.log_period_s,
            self.systematic.left_wheel_diameter_m,
            self.systematic.right_wheel_diameter_m,
            self.systematic.wheel_base_m,
            self.control.control_period_s,
            self.control.accel_mps2,
            self.control.motor_time_constant_s,
            self.control.brake_time_constant_s,
            self.random.slip_correlation_m,
            self.random.motor_noise_time_s,
            self.protocol.run_distance_m,
            self.camera.fps,
            self.sim_dt_s,
        ];
        if pos.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return bad("lengths, periods, gains and rates must be positive");
        }
        if self.nominal.ticks_per_rev == 0 {
            return bad("ticks_per_rev must be positive");
        }
        if !ratio_ok(self.nominal.log_period_s, self.sim_dt_s)
            || !ratio_ok(self.control.control_period_s, self.sim_dt_s)
        {
            return bad("sim_dt_s must divide log_period_s and control_period_s");
        }
        if self.protocol.speeds_mps.is_empty()
            || self
                .protocol
                .speeds_mps
                .iter()
                .any(|v| !(v.is_finite() && *v > 0.0 && *v <= MAX_WHEEL_SPEED_MPS))
        {
            return bad(&format!("speeds_mps must be a non-empty list of speeds above 0 and at most {MAX_WHEEL_SPEED_MPS} m/s (a small robot's wheels turn no faster, and odocal dataset takes a faster step for a glitch)"));
        }
        let ranges = [
            self.protocol.pre_roll_s,
            self.protocol.post_roll_s,
            self.protocol.pause_s,
            self.protocol.carry_s,
            self.camera.lead_s,
            self.camera.tail_s,
        ];
        if ranges
            .iter()
            .any(|r| !(r[0].is_finite() && r[1].is_finite() && r[0] >= 0.0 && r[1] >= r[0]))
        {
            return bad("time ranges must be [min, max] with 0 <= min <= max");
        }
        let nonneg = [
            self.random.slip_sd,
            self.random.roughness_rad_per_sqrt_m,
            self.random.motor_noise_sd,
            self.camera.position_noise_m,
            self.camera.heading_noise_rad,
            self.systematic.left_slip_per_mps,
            self.systematic.right_slip_per_mps,
        ];
        if nonneg.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return bad("noise levels and slip coefficients must be >= 0");
        }
        Ok(())
    }

    /// The commanded speed of run `i` (speeds cycled).
    pub fn speed_of_run(&self, i: usize) -> f64 {
        let s = &self.protocol.speeds_mps;
        s[i % s.len()]
    }
}
