//! The simulation itself: the PID-controlled robot driving the protocol's runs.

use super::*;

use super::physics::{uniform, Robot};

#[derive(Clone, Copy, PartialEq)]
enum Phase {
    Rest,
    Driving,
    Braking,
}

/// Simulates one recording with runs at `speeds` (one run per entry), from a seed and a stream.
pub fn simulate_recording(
    cfg: &RobotSimConfig,
    speeds: &[f64],
    seed: u64,
    stream: u64,
) -> Result<SimulatedRecording, RobotSimError> {
    cfg.validate()?;
    if speeds.is_empty() || speeds.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(RobotSimError::Invalid(
            "a recording needs at least one positive speed".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let dt = cfg.sim_dt_s;
    let nom = &cfg.nominal;
    let sys = &cfg.systematic;
    let ctl = &cfg.control;
    let pro = &cfg.protocol;
    let count = 2.0 * std::f64::consts::PI / nom.ticks_per_rev as f64;
    let r_nom = 0.5 * nom.wheel_diameter_m;
    let k_slip = [sys.left_slip_per_mps, sys.right_slip_per_mps];
    let steps_per_log = (nom.log_period_s / dt).round() as i64;
    let steps_per_ctl = (ctl.control_period_s / dt).round() as i64;
    let record_every = ((0.005 / dt).round() as i64).max(1);
    let target_ticks = (pro.run_distance_m / (count * r_nom)).round() as i64;

    let lead = uniform(&mut rng, cfg.camera.lead_s);
    let place = |rng: &mut ChaCha8Rng| {
        let x = pro.start_x_m + uniform(rng, [-pro.start_x_jitter_m, pro.start_x_jitter_m]);
        let y = pro.start_y_m + uniform(rng, [-pro.start_y_range_m, pro.start_y_range_m]);
        let h: f64 = rng.sample::<f64, _>(StandardNormal) * pro.start_heading_sd_rad;
        Pose2::new(x, y, h)
    };
    let mut robot = Robot {
        pose: place(&mut rng),
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
    let mut runs = Vec::new();
    let mut visible = true;
    // Events of the current state machine.
    let mut next_start = t_of(0) + uniform(&mut rng, pro.pre_roll_s);
    let mut run_idx = 0usize;
    let mut phase = Phase::Rest;
    let mut run_start_t = 0.0;
    let mut start_pose = robot.pose;
    let mut start_path = 0.0;
    let mut ticks0 = [0i64; 2];
    let (mut integ, mut e_prev) = (0.0f64, 0.0f64);
    let mut log_end: Option<f64> = None;
    let mut carry: Option<(f64, f64)> = None;
    let mut camera_end = f64::INFINITY;

    loop {
        let t = t_of(step);
        if t > camera_end + 1e-9 {
            break;
        }
        // Log row (robot clock, from 0 until the log ends).
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
                visible,
            });
        }
        // Carrying the robot back: hidden, teleported at the start of the carry.
        if let Some((c0, c1)) = carry {
            if t >= c0 && visible && t < c1 {
                visible = false;
                robot.pose = place(&mut rng);
            }
            if t >= c1 && !visible {
                visible = true;
                carry = None;
            }
        }
        // Controller.
        if step % steps_per_ctl == 0 {
            match phase {
                Phase::Rest => {
                    if run_idx < speeds.len() && t >= next_start - 1e-9 {
                        phase = Phase::Driving;
                        run_start_t = t;
                        start_pose = robot.pose;
                        start_path = robot.path;
                        ticks0 = [robot.ticks(0, count), robot.ticks(1, count)];
                        integ = 0.0;
                        e_prev = 0.0;
                    }
                }
                Phase::Driving => {}
                Phase::Braking => {}
            }
            if phase == Phase::Driving {
                let v_cmd = speeds[run_idx];
                let v_set = (ctl.accel_mps2 * (t - run_start_t)).min(v_cmd);
                let dl = robot.ticks(0, count) - ticks0[0];
                let dr = robot.ticks(1, count) - ticks0[1];
                if dl >= target_ticks {
                    phase = Phase::Braking;
                    robot.omega_cmd = [0.0, 0.0];
                } else {
                    let e = (dl - dr) as f64;
                    integ += e * ctl.control_period_s;
                    let de = (e - e_prev) / ctl.control_period_s;
                    e_prev = e;
                    let ff = v_set / r_nom;
                    let pid = ctl.kp_rad_s_per_tick * e
                        + ctl.ki_rad_s_per_tick_s * integ
                        + ctl.kd_rad_per_tick * de;
                    robot.omega_cmd = [ff, (ff + pid).clamp(0.0, 3.0 * v_cmd / r_nom)];
                }
            }
            if phase == Phase::Braking && robot.omega.iter().all(|w| w.abs() < 1e-3) {
                robot.omega = [0.0, 0.0];
                phase = Phase::Rest;
                let v = speeds[run_idx];
                let end_pose = robot.pose;
                let rel = end_pose.relative_to(&start_pose);
                runs.push(RunTruth {
                    speed_mps: v,
                    motion_start_s: run_start_t,
                    motion_end_s: t,
                    start_pose,
                    end_pose,
                    end_in_start_frame: Pose2::new(rel.x_m, rel.y_m, wrap_angle(rel.theta_rad)),
                    path_length_m: robot.path - start_path,
                    effective: EffectiveGeometry {
                        left_wheel_diameter_m: sys.left_wheel_diameter_m * (1.0 - k_slip[0] * v),
                        right_wheel_diameter_m: sys.right_wheel_diameter_m * (1.0 - k_slip[1] * v),
                        wheel_base_m: sys.wheel_base_m,
                    },
                });
                run_idx += 1;
                if run_idx < speeds.len() {
                    let c0 = t + uniform(&mut rng, pro.pause_s);
                    let c1 = c0 + uniform(&mut rng, pro.carry_s);
                    carry = Some((c0, c1));
                    next_start = c1 + uniform(&mut rng, pro.pre_roll_s);
                } else {
                    let end = t + uniform(&mut rng, pro.post_roll_s);
                    let end = (end / nom.log_period_s).ceil() * nom.log_period_s;
                    log_end = Some(end);
                    camera_end = end + uniform(&mut rng, cfg.camera.tail_s);
                }
            }
        }
        // Physics.
        if phase != Phase::Rest {
            let tau = if phase == Phase::Braking {
                ctl.brake_time_constant_s
            } else {
                ctl.motor_time_constant_s
            };
            // Both wheels slip with the body speed on a straight run.
            let v = robot.speed.abs();
            robot.physics_step(cfg, tau, [v, v], &mut rng);
        } else {
            robot.speed = 0.0;
        }
        step += 1;
        if step > 100_000_000 {
            return Err(RobotSimError::Invalid(
                "the run never ended (check gains and speeds)".into(),
            ));
        }
    }
    Ok(SimulatedRecording {
        clock_offset_s: lead,
        camera_end_s: camera_end + lead,
        log_period_s: nom.log_period_s,
        log,
        truth,
        truth_period_s: record_every as f64 * dt,
        runs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_sane() {
        let cfg = RobotSimConfig::default();
        let a = simulate_recording(&cfg, &[0.5], 7, 3).unwrap();
        let b = simulate_recording(&cfg, &[0.5], 7, 3).unwrap();
        assert_eq!(a, b);
        let c = simulate_recording(&cfg, &[0.5], 7, 4).unwrap();
        assert_ne!(a.log, c.log);
        assert_eq!(a.runs.len(), 1);
        let r = &a.runs[0];
        // About 1.5 m forward; a run at 0.5 m/s takes about 3 s.
        assert!((r.end_in_start_frame.x_m - 1.45).abs() < 0.1, "{r:?}");
        assert!(
            (r.motion_end_s - r.motion_start_s - 3.4).abs() < 0.5,
            "{r:?}"
        );
        // Log: 200 ms rows from robot time 0, cumulative ticks ~ 1.5 m / (pi 4.3 cm / 12).
        assert_eq!(a.log[0].index, 0);
        assert!(a.log.windows(2).all(|w| w[1].index == w[0].index + 1));
        let last = a.log.last().unwrap();
        assert!((last.left_ticks - 133).abs() <= 1, "{last:?}");
        // Camera starts before the log (offset = lead) and ends after it.
        assert!(a.clock_offset_s >= 0.3 && a.clock_offset_s <= 2.0);
        assert!(a.camera_end_s > a.log_time_s(last) + a.clock_offset_s);
        assert!(a.pose_at_camera_time(0.0).is_some());
    }

    #[test]
    fn log_times_are_written_as_a_robot_clock_counts_them() {
        let rec = simulate_recording(&RobotSimConfig::default(), &[0.5], 7, 3).unwrap();
        let csv = rec.odometry_log().unwrap().to_csv();
        // 19 × 0.2 s is 3.8000000000000003 as a product; a log reads 3.8.
        assert!(csv.lines().any(|l| l.starts_with("3.8,")), "{csv}");
        for line in csv.lines().skip(1) {
            let t = line.split(',').next().unwrap_or_default();
            let decimals = t.split('.').nth(1).map_or(0, str::len);
            assert!(decimals <= 6, "log time {t} has {decimals} decimals");
        }
    }

    #[test]
    fn heading_oscillates_and_runs_are_split_by_carries() {
        let cfg = RobotSimConfig::default();
        let rec = simulate_recording(&cfg, &[0.2, 0.7], 1, 0).unwrap();
        assert_eq!(rec.runs.len(), 2);
        assert!(rec.truth.iter().any(|p| !p.visible));
        // Heading relative to the run's mean direction swings by several degrees.
        let r = &rec.runs[0];
        let hs: Vec<f64> = rec
            .truth
            .iter()
            .filter(|p| p.t_robot_s > r.motion_start_s + 1.0 && p.t_robot_s < r.motion_end_s - 0.5)
            .map(|p| p.pose.theta_rad)
            .collect();
        let mean = hs.iter().sum::<f64>() / hs.len() as f64;
        let sd = (hs.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / hs.len() as f64).sqrt();
        assert!(sd > 0.01, "heading sd {sd}");
    }

    #[test]
    fn config_round_trips_and_is_checked() {
        let cfg = RobotSimConfig::default();
        let s = serde_json::to_string(&cfg).unwrap();
        let back: RobotSimConfig = serde_json::from_str(&s).unwrap();
        assert_eq!(back, cfg);
        let partial: RobotSimConfig =
            serde_json::from_str(r#"{"format":"odocal.robotsim/1","sim_dt_s":0.002}"#).unwrap();
        assert!(partial.validate().is_ok());
        let mut bad = cfg.clone();
        bad.sim_dt_s = 0.003;
        assert!(bad.validate().is_err());
        assert!(serde_json::from_str::<RobotSimConfig>(r#"{"bogus":1}"#).is_err());
    }
}
