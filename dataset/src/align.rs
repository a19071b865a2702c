//! Time alignment of a robot's odometry log with a camera trajectory.
//!
//! The clock offset (t_camera = t_robot + offset) is found in two steps:
//! 1. coarse: normalised cross-correlation of the speed profiles (odometry speed per log
//!    interval against the camera's speed over the same interval shifted by the lag), on a
//!    10 ms lag grid over every lag at which the log's motion lies inside the trajectory, with
//!    parabolic interpolation of the peak;
//! 2. fine, per run: the odometry travel at each log row is fitted to the camera's travel along
//!    the run direction at the shifted time (travel = a + b s + c s², absorbing odometry scale
//!    and slow slip), minimising the squared residual over the offset by a 2 ms scan and a
//!    golden-section search (continuous in the offset: the camera positions are interpolated
//!    between frames, so the result is sub-frame).
//!
//! Residuals are reported in metres (travel fit) and m/s (speed per log interval).

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::error::DatasetError;
use crate::kinematics::WheelGeometry;
use crate::odometry::{OdometryLog, WheelRevs};
use crate::segment::RunSegment;
use crate::trajectory::Trajectory;

/// Settings of the time alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignOptions {
    /// Longest gap between camera frames bridged by interpolation, seconds.
    pub max_frame_gap_s: f64,
    /// Lag grid step of the coarse cross-correlation, seconds.
    pub coarse_step_s: f64,
    /// Half width of the fine search around the coarse offset, seconds.
    pub refine_half_width_s: f64,
    /// Smallest acceptable speed-profile correlation.
    pub min_correlation: f64,
}

impl Default for AlignOptions {
    fn default() -> Self {
        Self {
            max_frame_gap_s: 0.15,
            coarse_step_s: 0.01,
            refine_half_width_s: 0.15,
            min_correlation: 0.8,
        }
    }
}

/// Result of the coarse cross-correlation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoarseOffset {
    /// Clock offset, seconds: t_camera = t_robot + offset.
    pub offset_s: f64,
    /// Peak normalised cross-correlation of the speed profiles.
    pub correlation: f64,
}

/// Result of the fine alignment of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alignment {
    /// Clock offset, seconds: t_camera = t_robot + offset.
    pub offset_s: f64,
    /// RMS residual of the travel fit, metres.
    pub residual_m: f64,
    /// RMS residual of the speed per log interval, m/s.
    pub residual_mps: f64,
    /// Log rows used.
    pub rows_used: usize,
}

/// Mean wheel travel per row, metres, with geometry `geom`.
fn travel(revs: &WheelRevs, geom: &WheelGeometry) -> Vec<f64> {
    let cl = std::f64::consts::PI * geom.left_wheel_diameter_m;
    let cr = std::f64::consts::PI * geom.right_wheel_diameter_m;
    revs.rev.iter().map(|r| 0.5 * (r[0] * cl + r[1] * cr)).collect()
}

/// Coarse clock offset of a whole log by speed-profile cross-correlation.
///
/// Fails with [`DatasetError::Mismatch`] when the log's motion cannot lie inside the trajectory
/// at any offset, or the trajectory never covers it; `what` names the pair in the message.
pub fn coarse_offset(
    log: &OdometryLog,
    revs: &WheelRevs,
    geom: &WheelGeometry,
    traj: &Trajectory,
    opts: &AlignOptions,
    what: &str,
) -> Result<CoarseOffset, DatasetError> {
    let n = log.len();
    let moving: Vec<usize> = (1..n).filter(|&i| log.moving_at(i)).collect();
    let (Some(&m0), Some(&m1)) = (moving.first(), moving.last()) else {
        return Err(DatasetError::Mismatch(format!("{what}: the odometry log shows no motion")));
    };
    let t = &revs.t_s;
    let (c0, c1) = (traj.start_s(), traj.end_s());
    let motion_s = t[m1] - t[m0 - 1];
    let lo = c0 - t[m0 - 1];
    let hi = c1 - t[m1];
    if traj.rows.len() < 2 || !(hi >= lo) {
        return Err(DatasetError::Mismatch(format!(
            "{what}: the log moves for {motion_s:.2} s but the trajectory covers {:.2} s; they cannot overlap \
             (check that the manifest pairs the right log and video/trajectory)",
            (c1 - c0).max(0.0)
        )));
    }
    let r = travel(revs, geom);
    let v_robot: Vec<f64> = (1..n).map(|k| (r[k] - r[k - 1]) / (t[k] - t[k - 1])).collect();
    let first = m0.saturating_sub(5).max(1);
    let last = (m1 + 5).min(n - 1);
    let need = (moving.len() * 4).div_ceil(5);
    let steps = ((hi - lo) / opts.coarse_step_s).floor() as usize;
    let mut scores = vec![f64::NEG_INFINITY; steps + 1];
    let mut a = Vec::with_capacity(last - first + 1);
    let mut b = Vec::with_capacity(last - first + 1);
    for (j, score) in scores.iter_mut().enumerate() {
        let lag = lo + j as f64 * opts.coarse_step_s;
        a.clear();
        b.clear();
        let mut moving_ok = 0;
        for k in first..=last {
            let (Some(p0), Some(p1)) = (
                traj.position_at(t[k - 1] + lag, opts.max_frame_gap_s),
                traj.position_at(t[k] + lag, opts.max_frame_gap_s),
            ) else {
                continue;
            };
            if log.moving_at(k) {
                moving_ok += 1;
            }
            a.push(v_robot[k - 1]);
            b.push((p1 - p0).norm() / (t[k] - t[k - 1]));
        }
        if moving_ok < need || a.len() < 3 {
            continue;
        }
        *score = ncc(&a, &b);
    }
    let (jbest, &best) = scores
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.total_cmp(y.1))
        .unwrap_or((0, &f64::NEG_INFINITY));
    if !best.is_finite() {
        return Err(DatasetError::Mismatch(format!(
            "{what}: the trajectory never covers the log's motion (too many missed frames?)"
        )));
    }
    let mut offset = lo + jbest as f64 * opts.coarse_step_s;
    if jbest > 0 && jbest < steps {
        let (ym, y0, yp) = (scores[jbest - 1], best, scores[jbest + 1]);
        let den = ym - 2.0 * y0 + yp;
        if ym.is_finite() && yp.is_finite() && den < 0.0 {
            offset += 0.5 * (ym - yp) / den * opts.coarse_step_s;
        }
    }
    Ok(CoarseOffset {
        offset_s: offset,
        correlation: best,
    })
}

/// Normalised cross-correlation (Pearson) of two equally long series.
fn ncc(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
}

/// Travel-fit problem of one run at a given offset.
struct Fine<'a> {
    t: Vec<f64>,
    r: Vec<f64>,
    traj: &'a Trajectory,
    origin: Vector2<f64>,
    dir: Vector2<f64>,
    scale: f64,
    max_gap: f64,
}

impl Fine<'_> {
    /// Camera travel along the run direction (in units of the run length) at each row.
    fn s(&self, offset: f64) -> Option<Vec<f64>> {
        self.t
            .iter()
            .map(|&tk| {
                self.traj
                    .position_at(tk + offset, self.max_gap)
                    .map(|p| (p.coords - self.origin).dot(&self.dir) / self.scale)
            })
            .collect()
    }

    /// Least-squares (a, b, c) of r ≈ a + b s + c s² and the sum of squared residuals.
    fn fit(&self, offset: f64) -> Option<(Vector3<f64>, f64, Vec<f64>)> {
        let s = self.s(offset)?;
        let mut m = Matrix3::zeros();
        let mut v = Vector3::zeros();
        for (&sk, &rk) in s.iter().zip(&self.r) {
            let f = Vector3::new(1.0, sk, sk * sk);
            m += f * f.transpose();
            v += f * rk;
        }
        let c = m.lu().solve(&v)?;
        let sse = s
            .iter()
            .zip(&self.r)
            .map(|(&sk, &rk)| (rk - c[0] - c[1] * sk - c[2] * sk * sk).powi(2))
            .sum();
        Some((c, sse, s))
    }

    fn cost(&self, offset: f64) -> f64 {
        self.fit(offset).map(|f| f.1).unwrap_or(f64::INFINITY)
    }
}

/// Fine clock offset of one run around a coarse offset; Err gives the reason the run is unusable.
pub fn refine_offset(
    revs: &WheelRevs,
    seg: &RunSegment,
    geom: &WheelGeometry,
    traj: &Trajectory,
    coarse_s: f64,
    opts: &AlignOptions,
) -> Result<Alignment, String> {
    let hw = opts.refine_half_width_s;
    let gap = opts.max_frame_gap_s;
    let first = seg.start_row.saturating_sub(2).max(seg.window_first);
    let last = (seg.end_row + 2).min(seg.window_last);
    let ok = |k: usize| traj.covers(revs.t_s[k] + coarse_s - hw - 0.05, revs.t_s[k] + coarse_s + hw + 0.05, gap);
    if !ok(seg.start_row) || !ok(seg.end_row) {
        return Err("the camera trajectory does not cover the start and end of the run".into());
    }
    let rows: Vec<usize> = (first..=last).filter(|&k| ok(k)).collect();
    let moving = rows.iter().filter(|&&k| k > seg.start_row && k <= seg.end_row).count();
    if moving * 5 < (seg.end_row - seg.start_row) * 4 || moving < 3 {
        return Err(format!(
            "the camera misses too much of the run ({moving} of {} log intervals covered)",
            seg.end_row - seg.start_row
        ));
    }
    let (Some(p0), Some(p1)) = (
        traj.position_at(revs.t_s[seg.start_row] + coarse_s, gap),
        traj.position_at(revs.t_s[seg.end_row] + coarse_s, gap),
    ) else {
        return Err("the camera trajectory does not cover the start and end of the run".into());
    };
    let d = p1 - p0;
    let len = d.norm();
    if len < 0.01 {
        return Err(format!("the camera sees no motion during the run ({:.1} mm)", len * 1e3));
    }
    let all_r = travel(revs, geom);
    let fine = Fine {
        t: rows.iter().map(|&k| revs.t_s[k]).collect(),
        r: rows.iter().map(|&k| (all_r[k] - all_r[seg.start_row]) / len).collect(),
        traj,
        origin: p0.coords,
        dir: d / len,
        scale: len,
        max_gap: gap,
    };
    // Scan, then golden section around the best scan point.
    let step = 0.002;
    let n = (2.0 * hw / step).round() as usize;
    let (mut best, mut best_cost) = (coarse_s, f64::INFINITY);
    for j in 0..=n {
        let o = coarse_s - hw + j as f64 * step;
        let c = fine.cost(o);
        if c < best_cost {
            best = o;
            best_cost = c;
        }
    }
    if !best_cost.is_finite() {
        return Err("the travel fit failed (degenerate camera motion)".into());
    }
    let (mut a, mut b) = (best - step, best + step);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (fine.cost(x1), fine.cost(x2));
    while b - a > 1e-6 {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = fine.cost(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = fine.cost(x2);
        }
    }
    let offset = if f1.min(f2) <= best_cost { 0.5 * (a + b) } else { best };
    let Some((c, sse, s)) = fine.fit(offset) else {
        return Err("the travel fit failed (degenerate camera motion)".into());
    };
    let model: Vec<f64> = s.iter().map(|&sk| c[0] + c[1] * sk + c[2] * sk * sk).collect();
    let mut sq = 0.0;
    let mut m = 0;
    for k in 1..fine.t.len() {
        let dt = fine.t[k] - fine.t[k - 1];
        let e = ((fine.r[k] - fine.r[k - 1]) - (model[k] - model[k - 1])) * len / dt;
        sq += e * e;
        m += 1;
    }
    Ok(Alignment {
        offset_s: offset,
        residual_m: (sse / fine.t.len() as f64).sqrt() * len,
        residual_mps: (sq / m.max(1) as f64).sqrt(),
        rows_used: fine.t.len(),
    })
}
