//! Any path: a plan of straight legs, arcs and turns in place, driven by a wheel-position
//! controller on the robot's own encoders (so the robot follows the plan as its odometry
//! believes it, and its true path departs from it by the systematic and random errors), and
//! the plans odometry is judged on: random waypoint tours and Borenstein's UMBMark square.

use std::f64::consts::PI;

use super::physics::{uniform, Robot};
use super::*;

/// One leg of a plan, in the robot's own (nominal) terms. Angles are counter-clockwise
/// positive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Segment {
    /// Straight ahead (negative: backwards).
    Straight {
        /// Distance, metres.
        distance_m: f64,
        /// Cruise speed, m/s.
        speed_mps: f64,
    },
    /// A circular arc of the wheels' midpoint.
    Arc {
        /// Radius, metres (> half the wheel base).
        radius_m: f64,
        /// Heading change, radians (positive: to the left).
        angle_rad: f64,
        /// Cruise speed of the midpoint, m/s.
        speed_mps: f64,
    },
    /// A turn in place.
    Turn {
        /// Heading change, radians (positive: counter-clockwise).
        angle_rad: f64,
        /// Cruise speed of each wheel, m/s.
        wheel_speed_mps: f64,
    },
}

impl Segment {
    /// Nominal wheel travels [left, right] of the leg, metres, on a robot of wheel base `b`.
    fn wheel_travel_m(&self, b: f64) -> [f64; 2] {
        match *self {
            Segment::Straight { distance_m, .. } => [distance_m, distance_m],
            Segment::Arc {
                radius_m,
                angle_rad,
                ..
            } => {
                let s = angle_rad.signum();
                let r = radius_m.abs();
                // Left turn: the left wheel is inside.
                [
                    angle_rad.abs() * (r - s * 0.5 * b),
                    angle_rad.abs() * (r + s * 0.5 * b),
                ]
            }
            Segment::Turn { angle_rad, .. } => [-0.5 * b * angle_rad, 0.5 * b * angle_rad],
        }
    }

    /// Cruise speed of the faster wheel, m/s.
    fn peak_wheel_speed_mps(&self, b: f64) -> f64 {
        match *self {
            Segment::Straight { speed_mps, .. } => speed_mps,
            Segment::Arc {
                radius_m,
                speed_mps,
                ..
            } => speed_mps * (radius_m.abs() + 0.5 * b) / radius_m.abs(),
            Segment::Turn {
                wheel_speed_mps, ..
            } => wheel_speed_mps,
        }
    }

    fn check(&self, b: f64) -> Result<(), RobotSimError> {
        let bad = |m: String| Err(RobotSimError::Invalid(m));
        let finite = match *self {
            Segment::Straight {
                distance_m,
                speed_mps,
            } => [distance_m, speed_mps, 1.0],
            Segment::Arc {
                radius_m,
                angle_rad,
                speed_mps,
            } => [radius_m, angle_rad, speed_mps],
            Segment::Turn {
                angle_rad,
                wheel_speed_mps,
            } => [angle_rad, wheel_speed_mps, 1.0],
        };
        if finite.iter().any(|v| !v.is_finite()) {
            return bad(format!("plan leg {self:?} has a non-finite number"));
        }
        if self.peak_wheel_speed_mps(b) <= 0.0 {
            return bad(format!("plan leg {self:?} needs a positive speed"));
        }
        if let Segment::Arc { radius_m, .. } = *self {
            if radius_m.abs() <= 0.5 * b {
                return bad(format!(
                    "plan arc radius {radius_m} m must exceed half the wheel base ({} m); use a turn",
                    0.5 * b
                ));
            }
        }
        Ok(())
    }
}

/// A path to drive: legs separated by short stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// What the plan is ("tour", "umbmark-cw", ...).
    pub name: String,
    /// The legs in order.
    pub segments: Vec<Segment>,
}

/// The kinds of path `odocal synth experiment --paths` simulates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// The reference experiment's straight runs (the straight-run protocol).
    Straight,
    /// Random waypoint tours: turns in place with straight legs, and arcs.
    Tours,
    /// Borenstein's UMBMark: a square driven clockwise and counter-clockwise, alternately.
    Umbmark,
}

/// Stop between legs, seconds.
const LEG_STOP_S: f64 = 0.4;

impl Plan {
    /// Borenstein's UMBMark square of side `side_m`, clockwise or counter-clockwise, its sides
    /// at `speed_mps` and its turns in place at `turn_wheel_speed_mps`.
    pub fn umbmark(
        side_m: f64,
        clockwise: bool,
        speed_mps: f64,
        turn_wheel_speed_mps: f64,
    ) -> Self {
        let turn = if clockwise { -PI / 2.0 } else { PI / 2.0 };
        let mut segments = Vec::with_capacity(8);
        for _ in 0..4 {
            segments.push(Segment::Straight {
                distance_m: side_m,
                speed_mps,
            });
            segments.push(Segment::Turn {
                angle_rad: turn,
                wheel_speed_mps: turn_wheel_speed_mps,
            });
        }
        Self {
            name: if clockwise {
                "umbmark-cw"
            } else {
                "umbmark-ccw"
            }
            .into(),
            segments,
        }
    }

    /// A random waypoint tour of `legs` legs inside a square of `area_m` around the start (in
    /// the robot's own frame): each leg reaches the next waypoint either by a turn in place
    /// and a straight leg or by one arc, at a speed drawn from `speeds_mps`.
    pub fn tour(legs: usize, area_m: f64, speeds_mps: &[f64], rng: &mut ChaCha8Rng) -> Self {
        let mut pose = Pose2::default();
        let mut segments = Vec::new();
        let half = 0.5 * area_m;
        let pick = |rng: &mut ChaCha8Rng| speeds_mps[rng.gen_range(0..speeds_mps.len().max(1))];
        while segments.len() < 2 * legs {
            let goal = Pose2::new(rng.gen_range(-half..half), rng.gen_range(-half..half), 0.0);
            let local = goal.relative_to(&pose);
            let dist = local.x_m.hypot(local.y_m);
            if dist < 0.3 {
                continue;
            }
            let speed = pick(rng);
            // The arc through the goal tangent to the heading: radius d^2 / (2 |lateral|),
            // turning by twice the bearing.
            let bearing = local.y_m.atan2(local.x_m);
            let radius = dist * dist / (2.0 * local.y_m.abs().max(1e-9));
            let arc_ok = bearing.abs() < 0.6 * PI && radius > 0.2;
            if arc_ok && rng.gen_bool(0.5) {
                let angle = 2.0 * bearing;
                segments.push(Segment::Arc {
                    radius_m: radius,
                    angle_rad: angle,
                    speed_mps: speed,
                });
                let chord = Pose2::new(local.x_m, local.y_m, angle);
                pose = pose.compose(&chord);
            } else {
                segments.push(Segment::Turn {
                    angle_rad: bearing,
                    wheel_speed_mps: 0.5 * speed,
                });
                segments.push(Segment::Straight {
                    distance_m: dist,
                    speed_mps: speed,
                });
                pose = pose.compose(&Pose2::new(0.0, 0.0, bearing));
                pose = pose.compose(&Pose2::new(dist, 0.0, 0.0));
            }
        }
        Self {
            name: "tour".into(),
            segments,
        }
    }
}

/// Trapezoidal progress along a leg of length `len` (> 0) with peak speed `v` and
/// acceleration `a`: distance covered after `t` seconds, and the leg's duration.
fn trapezoid(len: f64, v: f64, a: f64, t: f64) -> (f64, f64) {
    let t_acc = (v / a).min((len / a).sqrt());
    let v_peak = a * t_acc;
    let d_acc = 0.5 * a * t_acc * t_acc;
    let t_cruise = ((len - 2.0 * d_acc) / v_peak).max(0.0);
    let total = 2.0 * t_acc + t_cruise;
    let s = if t <= 0.0 {
        0.0
    } else if t < t_acc {
        0.5 * a * t * t
    } else if t < t_acc + t_cruise {
        d_acc + v_peak * (t - t_acc)
    } else if t < total {
        let r = total - t;
        len - 0.5 * a * r * r
    } else {
        len
    };
    (s.min(len), total)
}

/// Simulates the robot driving `plan` (one recording: rest, the legs, rest), from a seed and
/// a stream. Each wheel follows its planned angle through a PI loop on its encoder counts;
/// slip grows with each wheel's own ground speed. The one [`RunTruth`] covers the whole plan
/// (its `effective` geometry is the true one at the mean leg speed).
pub fn simulate_plan(
    cfg: &RobotSimConfig,
    plan: &Plan,
    seed: u64,
    stream: u64,
) -> Result<SimulatedRecording, RobotSimError> {
    cfg.validate()?;
    let nom = &cfg.nominal;
    let b_nom = nom.wheel_base_m;
    if plan.segments.is_empty() {
        return Err(RobotSimError::Invalid(format!(
            "plan '{}' has no legs",
            plan.name
        )));
    }
    for s in &plan.segments {
        s.check(b_nom)?;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let dt = cfg.sim_dt_s;
    let sys = &cfg.systematic;
    let ctl = &cfg.control;
    let pro = &cfg.protocol;
    let count = 2.0 * PI / nom.ticks_per_rev as f64;
    let r_nom = 0.5 * nom.wheel_diameter_m;
    let steps_per_log = (nom.log_period_s / dt).round() as i64;
    let steps_per_ctl = (ctl.control_period_s / dt).round() as i64;
    let record_every = ((0.005 / dt).round() as i64).max(1);

    let lead = uniform(&mut rng, cfg.camera.lead_s);
    let start = {
        let x = pro.start_x_m + uniform(&mut rng, [-pro.start_x_jitter_m, pro.start_x_jitter_m]);
        let y = pro.start_y_m + uniform(&mut rng, [-pro.start_y_range_m, pro.start_y_range_m]);
        let h: f64 = rng.sample::<f64, _>(StandardNormal) * pro.start_heading_sd_rad;
        Pose2::new(x, y, h)
    };
    let mut robot = Robot {
        pose: start,
        phi: [0.0; 2],
        phi0: [rng.gen_range(0.0..count), rng.gen_range(0.0..count)],
        omega: [0.0; 2],
        omega_cmd: [0.0; 2],
        slip: [rng.sample(StandardNormal), rng.sample(StandardNormal)],
        motor: [0.0; 2],
        speed: 0.0,
        wheel_speed: [0.0; 2],
        path: 0.0,
    };
    let mut step: i64 = -((lead / dt / record_every as f64).ceil() as i64) * record_every;
    let t_of = |s: i64| s as f64 * dt;
    let mut truth = Vec::new();
    let mut log = Vec::new();
    let motion_start = uniform(&mut rng, pro.pre_roll_s);

    // The leg being driven: index, start time, wheel angles at its start, planned wheel angle
    // changes, its length (faster wheel, metres) and peak speed.
    struct Leg {
        start_t: f64,
        phi_start: [f64; 2],
        dphi: [f64; 2],
        len_m: f64,
        peak_mps: f64,
        integ: [f64; 2],
        braking: bool,
    }
    let mut leg_idx = 0usize;
    let mut leg: Option<Leg> = None;
    let mut next_leg_t = motion_start;
    let mut log_end: Option<f64> = None;
    let mut camera_end = f64::INFINITY;
    let mut motion_end = motion_start;
    let mut moving = false;
    let mut speed_sum = 0.0;

    loop {
        let t = t_of(step);
        if t > camera_end + 1e-9 {
            break;
        }
        if step >= 0 && step % steps_per_log == 0 && log_end.is_none_or(|e| t <= e + 1e-9) {
            log.push(TickRow {
                index: (step / steps_per_log) as u64,
                left_ticks: robot.ticks(0, count),
                right_ticks: robot.ticks(1, count),
            });
        }
        if step % record_every == 0 {
            truth.push(TruePose {
                t_robot_s: t,
                pose: robot.pose,
                visible: true,
            });
        }
        if step % steps_per_ctl == 0 {
            if leg.is_none() && leg_idx < plan.segments.len() && t >= next_leg_t - 1e-9 {
                let seg = plan.segments[leg_idx];
                let travel = seg.wheel_travel_m(b_nom);
                leg = Some(Leg {
                    start_t: t,
                    // The plan continues from where the encoders say the last leg ended.
                    phi_start: [
                        robot.ticks(0, count) as f64 * count - robot.phi0[0] + 0.5 * count,
                        robot.ticks(1, count) as f64 * count - robot.phi0[1] + 0.5 * count,
                    ],
                    dphi: [travel[0] / r_nom, travel[1] / r_nom],
                    len_m: travel[0].abs().max(travel[1].abs()),
                    peak_mps: seg.peak_wheel_speed_mps(b_nom),
                    integ: [0.0; 2],
                    braking: false,
                });
                speed_sum += seg.peak_wheel_speed_mps(b_nom);
                moving = true;
            }
            if let Some(l) = leg.as_mut() {
                let (s, total) = trapezoid(l.len_m, l.peak_mps, ctl.accel_mps2, t - l.start_t);
                let (s_next, _) = trapezoid(
                    l.len_m,
                    l.peak_mps,
                    ctl.accel_mps2,
                    t - l.start_t + ctl.control_period_s,
                );
                let frac = if l.len_m > 0.0 { s / l.len_m } else { 1.0 };
                let rate = if l.len_m > 0.0 {
                    (s_next - s) / l.len_m / ctl.control_period_s
                } else {
                    0.0
                };
                if !l.braking && t - l.start_t >= total + 0.1 {
                    l.braking = true;
                    robot.omega_cmd = [0.0; 2];
                }
                if !l.braking {
                    for w in 0..2 {
                        let reference = l.phi_start[w] + frac * l.dphi[w];
                        let seen =
                            robot.ticks(w, count) as f64 * count - robot.phi0[w] + 0.5 * count;
                        // Error in counts, as the controller sees it through its encoder.
                        let e = (reference - seen) / count;
                        l.integ[w] += e * ctl.control_period_s;
                        robot.omega_cmd[w] = rate * l.dphi[w]
                            + ctl.kp_rad_s_per_tick * e
                            + ctl.ki_rad_s_per_tick_s * l.integ[w];
                    }
                } else if robot.omega.iter().all(|w| w.abs() < 1e-3) {
                    robot.omega = [0.0; 2];
                    leg = None;
                    moving = false;
                    leg_idx += 1;
                    next_leg_t = t + LEG_STOP_S;
                    if leg_idx == plan.segments.len() {
                        motion_end = t;
                        let end = t + uniform(&mut rng, pro.post_roll_s);
                        let end = (end / nom.log_period_s).ceil() * nom.log_period_s;
                        log_end = Some(end);
                        camera_end = end + uniform(&mut rng, cfg.camera.tail_s);
                    }
                }
            }
        }
        if moving {
            let tau = if leg.as_ref().is_some_and(|l| l.braking) {
                ctl.brake_time_constant_s
            } else {
                ctl.motor_time_constant_s
            };
            let v = [robot.wheel_speed[0].abs(), robot.wheel_speed[1].abs()];
            robot.physics_step(cfg, tau, v, &mut rng);
        } else {
            robot.speed = 0.0;
            robot.wheel_speed = [0.0; 2];
        }
        step += 1;
        if step > 200_000_000 {
            return Err(RobotSimError::Invalid(format!(
                "plan '{}' never ended (check gains and speeds)",
                plan.name
            )));
        }
    }
    let v_mean = speed_sum / plan.segments.len() as f64;
    let end_pose = robot.pose;
    let rel = end_pose.relative_to(&start);
    let k_slip = [sys.left_slip_per_mps, sys.right_slip_per_mps];
    Ok(SimulatedRecording {
        clock_offset_s: lead,
        camera_end_s: camera_end + lead,
        log_period_s: nom.log_period_s,
        log,
        truth,
        truth_period_s: record_every as f64 * dt,
        runs: vec![RunTruth {
            speed_mps: v_mean,
            motion_start_s: motion_start,
            motion_end_s: motion_end,
            start_pose: start,
            end_pose,
            end_in_start_frame: Pose2::new(rel.x_m, rel.y_m, wrap_angle(rel.theta_rad)),
            path_length_m: robot.path,
            effective: EffectiveGeometry {
                left_wheel_diameter_m: sys.left_wheel_diameter_m * (1.0 - k_slip[0] * v_mean),
                right_wheel_diameter_m: sys.right_wheel_diameter_m * (1.0 - k_slip[1] * v_mean),
                wheel_base_m: sys.wheel_base_m,
            },
        }],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_odometry_of_a_square_closes_and_the_truth_does_not() {
        let cfg = RobotSimConfig::default();
        let plan = Plan::umbmark(1.0, true, 0.4, 0.2);
        let rec = simulate_plan(&cfg, &plan, 3, 0).unwrap();
        let log = rec.odometry_log().unwrap();
        let robot = odocal_dataset::RobotParams::default();
        let revs = log.wheel_revs(&robot);
        let poses = odocal_dataset::kinematics::dead_reckon(
            &revs.rev,
            &odocal_dataset::WheelGeometry::nominal(&robot),
        );
        let end = poses.last().unwrap();
        // The controller closes the square on its own encoders to a few counts.
        assert!(end.x_m.hypot(end.y_m) < 0.05, "odometry end {end:?}");
        assert!((end.theta_rad + 2.0 * PI).abs() < 0.2, "{end:?}");
        // The true square does not close: wheel base and diameters are off by percents.
        let e = rec.runs[0].end_in_start_frame;
        assert!(e.x_m.hypot(e.y_m) > 0.05, "true end {e:?}");
        let same = simulate_plan(&cfg, &plan, 3, 0).unwrap();
        assert_eq!(rec, same);
    }

    #[test]
    fn tours_mix_arcs_turns_and_straight_legs() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let p = Plan::tour(12, 2.0, &[0.2, 0.5], &mut rng);
        let has = |f: fn(&Segment) -> bool| p.segments.iter().any(f);
        assert!(has(|s| matches!(s, Segment::Arc { .. })));
        assert!(has(|s| matches!(s, Segment::Turn { .. })));
        assert!(has(|s| matches!(s, Segment::Straight { .. })));
        let rec = simulate_plan(&RobotSimConfig::default(), &p, 5, 1).unwrap();
        assert!(rec.runs[0].path_length_m > 5.0, "{:?}", rec.runs[0]);
    }
}
