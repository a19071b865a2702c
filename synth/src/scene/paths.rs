//! Timed floor paths for the renderer: the demonstration drive, straight drives, and the
//! pose and frame times along them.

use super::*;

/// Pose of a timed trajectory at time `t_s`: linear interpolation of position
/// and (wrapped) heading; clamped to the first/last sample outside the range.
pub fn pose_at(trajectory: &[(f64, Pose2)], t_s: f64) -> Option<Pose2> {
    let first = trajectory.first()?;
    let last = trajectory.last()?;
    if t_s <= first.0 {
        return Some(first.1);
    }
    if t_s >= last.0 {
        return Some(last.1);
    }
    let i = trajectory.partition_point(|s| s.0 <= t_s).saturating_sub(1);
    let (ta, a) = trajectory[i];
    let (tb, b) = trajectory[(i + 1).min(trajectory.len() - 1)];
    let w = if tb > ta { (t_s - ta) / (tb - ta) } else { 0.0 };
    let mut p = a.lerp(&b, w);
    p.theta_rad = wrap_angle(p.theta_rad);
    Some(p)
}

/// A demonstration drive in view of the default camera: a closed rounded path
/// (ellipse 1.0 m × 0.5 m semi-axes around `centre`, e.g. the [`nadir`]) at a speed varying
/// smoothly between `v_min_mps` and `v_max_mps`, with a small heading
/// oscillation (±1.5° at 2.3 Hz) as small robots show. Sampled every 2 ms.
pub fn demo_trajectory(
    centre: Point2<f64>,
    duration_s: f64,
    v_min_mps: f64,
    v_max_mps: f64,
    seed: u64,
) -> Vec<(f64, Pose2)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phase_v: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    let phase_s: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    let start: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
    let (a, b) = (1.0, 0.5);
    let dt = 0.002;
    let n = (duration_s / dt).ceil() as usize + 1;
    let mut out = Vec::with_capacity(n);
    let mut u = start; // ellipse parameter
    for k in 0..n {
        let t = k as f64 * dt;
        let (su, cu) = u.sin_cos();
        let (dx, dy) = (-a * su, b * cu);
        let heading =
            dy.atan2(dx) + 1.5f64.to_radians() * (std::f64::consts::TAU * 2.3 * t + phase_s).sin();
        out.push((
            t,
            Pose2::new(centre.x + a * cu, centre.y + b * su, wrap_angle(heading)),
        ));
        let v = v_min_mps
            + (v_max_mps - v_min_mps)
                * 0.5
                * (1.0 + (std::f64::consts::TAU * t / 3.7 + phase_v).sin());
        u += v * dt / dx.hypot(dy);
    }
    out
}

/// A straight drive from `from` to `to` (floor metres) at constant speed, heading
/// along the motion; sampled every 2 ms.
pub fn straight_trajectory(
    from: Point2<f64>,
    to: Point2<f64>,
    speed_mps: f64,
) -> Vec<(f64, Pose2)> {
    let d = to - from;
    let heading = d.y.atan2(d.x);
    let duration = d.norm() / speed_mps.max(1e-6);
    let n = (duration / 0.002).ceil().max(1.0) as usize;
    (0..=n)
        .map(|k| {
            let w = k as f64 / n as f64;
            let p = from + d * w;
            (w * duration, Pose2::new(p.x, p.y, heading))
        })
        .collect()
}

/// Frame times of a video at `fps` covering the trajectory: t = t0 + k / fps.
pub fn frame_times(trajectory: &[(f64, Pose2)], fps: f64) -> Vec<f64> {
    let (Some(a), Some(b)) = (trajectory.first(), trajectory.last()) else {
        return vec![];
    };
    let n = ((b.0 - a.0) * fps + 1e-9).floor() as usize + 1;
    (0..n).map(|k| a.0 + k as f64 / fps).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_interpolation_wraps_heading() {
        let tr = [
            (0.0, Pose2::new(0.0, 0.0, 3.1)),
            (1.0, Pose2::new(1.0, 0.0, -3.1)),
        ];
        let p = pose_at(&tr, 0.5).unwrap();
        assert!((p.x_m - 0.5).abs() < 1e-12);
        assert!(wrap_angle(p.theta_rad - std::f64::consts::PI).abs() < 1e-9);
    }
}
