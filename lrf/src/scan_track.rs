//! Tracking through a scan sequence: match near the predicted pose, fall
//! back to global search, and keep several hypotheses until the motion
//! resolves them.

use nalgebra::{Matrix3, Rotation2, Vector2};
use odocal_core::{wrap_angle, Pose2};

use crate::{Detection, Hypothesis, Localizer, Scan, Status};

/// Result of processing one scan of a sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFix {
    /// Time of the scan, seconds.
    pub t_s: f64,
    /// ok / ambiguous / lost.
    pub status: Status,
    /// Best pose (sensor in map), if any.
    pub pose: Option<Pose2>,
    /// Landmarks matched for the best pose.
    pub n_landmarks: usize,
    /// Detections in the scan.
    pub n_detections: usize,
    /// Hypotheses still alive.
    pub n_hypotheses: usize,
    /// Score of the best hypothesis (matches − missing).
    pub score: f64,
    /// "track" if the pose came from tracking, "global" if from global search.
    pub mode: &'static str,
    /// Covariance of the best pose (x, y, θ; m², m·rad, rad²): its Cramér–Rao bound.
    pub pose_cov: Option<Matrix3<f64>>,
    /// The detections were de-skewed with the tracked motion; false when there was none yet
    /// (the first scans of a track), so the pose still carries the sweep's skew.
    pub deskewed: bool,
    /// The hypotheses matched to this scan, best first (tracks that coast are left out).
    pub hypotheses: Vec<Hypothesis>,
}

impl ScanFix {
    /// A scan without a pose: `n_detections` reflectors seen, `n_hypotheses` still tracked.
    fn lost(t_s: f64, n_detections: usize, n_hypotheses: usize, mode: &'static str) -> Self {
        ScanFix {
            t_s,
            status: Status::Lost,
            pose: None,
            n_landmarks: 0,
            n_detections,
            n_hypotheses,
            score: 0.0,
            mode,
            pose_cov: None,
            deskewed: false,
            hypotheses: Vec::new(),
        }
    }
}

#[derive(Debug, Clone)]
struct Track {
    pose: Pose2,
    /// Velocity in the map frame: dx/dt, dy/dt (m/s), dθ/dt (rad/s).
    vel: [f64; 3],
    /// `vel` was measured (the track has been updated at least once).
    vel_known: bool,
    t_s: f64,
    /// Accumulated score (evidence) since the track was created.
    cum: f64,
    /// Landmarks matched since the track was created: `cum` without the landmarks missed.
    cum_matched: f64,
    /// True once the track was the only consistent hypothesis.
    confirmed: bool,
    last: Hypothesis,
    coasting: u32,
    /// `pose` came from de-skewed detections: it is the sensor's pose at its scan's time, not
    /// somewhere along its sweep.
    deskewed: bool,
}

/// Sequential localisation with history.
#[derive(Debug, Clone)]
pub struct ScanTracker<'a> {
    loc: &'a Localizer,
    tracks: Vec<Track>,
    /// Accumulated-score lead that resolves an ambiguity.
    pub history_margin: f64,
    /// At most this many hypotheses are tracked.
    pub max_tracks: usize,
    /// Scans a track may go unmatched before it is dropped.
    pub max_coast: u32,
}

impl<'a> ScanTracker<'a> {
    /// A tracker with no prior.
    pub fn new(loc: &'a Localizer) -> ScanTracker<'a> {
        ScanTracker {
            loc,
            tracks: Vec::new(),
            history_margin: 3.0,
            max_tracks: 8,
            max_coast: 5,
        }
    }

    /// Forgets all hypotheses (next scan is localised globally).
    pub fn reset(&mut self) {
        self.tracks.clear();
    }

    fn predict(tr: &Track, t_s: f64) -> (Pose2, f64) {
        let dt = (t_s - tr.t_s).clamp(0.0, 2.0);
        let p = Pose2::new(
            tr.pose.x_m + tr.vel[0] * dt,
            tr.pose.y_m + tr.vel[1] * dt,
            wrap_angle(tr.pose.theta_rad + tr.vel[2] * dt),
        );
        (p, dt)
    }

    /// Moves `tr` to `h`, found at `t_s` from detections `deskewed` or not.
    fn update(tr: &mut Track, h: Hypothesis, t_s: f64, deskewed: bool) {
        let dt = t_s - tr.t_s;
        if dt > 1e-6 && tr.coasting == 0 {
            let v = [
                (h.pose.x_m - tr.pose.x_m) / dt,
                (h.pose.y_m - tr.pose.y_m) / dt,
                wrap_angle(h.pose.theta_rad - tr.pose.theta_rad) / dt,
            ];
            // A new track's first velocity is the measured one, not half of it.
            let keep = if tr.vel_known { 0.5 } else { 0.0 };
            for (w, vk) in tr.vel.iter_mut().zip(v) {
                *w = keep * *w + (1.0 - keep) * vk;
            }
            tr.vel_known = true;
        }
        tr.pose = h.pose;
        tr.t_s = t_s;
        tr.cum += h.score;
        tr.cum_matched += h.matches.len() as f64;
        tr.coasting = 0;
        tr.last = h;
        tr.deskewed = deskewed;
    }

    fn new_track(h: Hypothesis, t_s: f64, confirmed: bool) -> Track {
        Track {
            pose: h.pose,
            vel: [0.0; 3],
            vel_known: false,
            t_s,
            cum: h.score,
            cum_matched: h.matches.len() as f64,
            confirmed,
            last: h,
            coasting: 0,
            deskewed: false,
        }
    }

    /// Processes the next scan taken at `t_s`.
    pub fn process(&mut self, scan: &Scan, t_s: f64) -> ScanFix {
        let measured = self.loc.detections(scan);
        let n_det = measured.len();
        // The beams were taken while the sensor moved: the best track's motion puts them in
        // the frame of the scan's time (for the global search; each track uses its own).
        let motion = self
            .tracks
            .first()
            .filter(|t| t.vel_known)
            .map(|tr| (tr.vel, Self::predict(tr, t_s).0));
        let dets = match motion {
            Some((vel, at)) => deskewed(&measured, vel, &at),
            None => measured.clone(),
        };
        let mut mode = "track";
        // 1. Tracking mode for every live hypothesis.
        let mut matched_any = false;
        let mut results: Vec<Option<Hypothesis>> = Vec::with_capacity(self.tracks.len());
        for tr in &self.tracks {
            let (pred, dt) = Self::predict(tr, t_s);
            let dt = dt + 0.1 * tr.coasting as f64;
            let (gate_m, gate_rad) = (0.02 + 0.3 * dt, 0.005 + 0.1 * dt);
            if !tr.vel_known {
                let h = self.loc.track(scan, &measured, pred, gate_m, gate_rad);
                matched_any |= h.is_some();
                results.push(h);
                continue;
            }
            let h = self.loc.track(
                scan,
                &deskewed(&measured, tr.vel, &pred),
                pred,
                gate_m,
                gate_rad,
            );
            // The track's smoothed velocity lags behind the sweep by a scan or two; the motion
            // from its last pose to this fit is nearer the sweep's time: the fit is repeated with
            // it (the heading error of a sensor turning at a changing rate halves).
            let h = h.map(|h| {
                let dt = t_s - tr.t_s;
                let swept = self.loc.cfg.sensor.beam_interval_s(scan) > 0.0;
                // From a pose left with its sweep's skew (the second of a track), the motion
                // is off by half a sweep's: the first de-skewed pose was 7–12σ off with it.
                if dt <= 1e-6 || tr.coasting > 0 || !swept || !tr.deskewed {
                    return h;
                }
                let vel = [
                    (h.pose.x_m - tr.pose.x_m) / dt,
                    (h.pose.y_m - tr.pose.y_m) / dt,
                    wrap_angle(h.pose.theta_rad - tr.pose.theta_rad) / dt,
                ];
                let dets = deskewed(&measured, vel, &h.pose);
                self.loc
                    .track(scan, &dets, h.pose, gate_m, gate_rad)
                    .unwrap_or(h)
            });
            matched_any |= h.is_some();
            results.push(h);
        }
        if matched_any {
            // Hypotheses that fail while another one matches are refuted.
            let n_before = self.tracks.len();
            let mut kept = Vec::new();
            for (mut tr, h) in self.tracks.drain(..).zip(results) {
                if let Some(h) = h {
                    // Each track matched detections de-skewed with its own motion, if it had one.
                    let deskewed = tr.vel_known;
                    Self::update(&mut tr, h, t_s, deskewed);
                    if kept.iter().all(|k: &Track| !same(&k.pose, &tr.pose)) {
                        kept.push(tr);
                    }
                }
            }
            self.tracks = kept;
            self.prune();
            if n_before > 1 && self.tracks.len() == 1 {
                // The others were refuted by the scans: the survivor is the pose.
                self.tracks[0].confirmed = true;
            }
        } else {
            // 2. Global search, preferring a hypothesis consistent with the history.
            mode = "global";
            let g = self.loc.global(scan, &dets);
            let mut from_history = None;
            for tr in self.tracks.iter().filter(|t| t.confirmed) {
                let (pred, _) = Self::predict(tr, t_s);
                if let Some(h) = g.hypotheses.iter().find(|h| {
                    (h.pose.position() - pred.position()).norm() < 0.3
                        && wrap_angle(h.pose.theta_rad - pred.theta_rad).abs() < 0.2
                }) {
                    from_history = Some((tr.clone(), h.clone()));
                    break;
                }
            }
            if let Some((mut tr, h)) = from_history {
                Self::update(&mut tr, h, t_s, motion.is_some());
                self.tracks = vec![tr];
            } else if g.status == Status::Lost {
                for tr in &mut self.tracks {
                    tr.coasting += 1;
                }
                let max_coast = self.max_coast;
                self.tracks.retain(|t| t.coasting <= max_coast);
                return ScanFix::lost(t_s, n_det, self.tracks.len(), mode);
            } else {
                // A pose far from where a confirmed track predicts is a jump: it is not believed
                // until the next scans refute the old track (which coasts beside it meanwhile).
                let jump = self.tracks.iter().any(|t| t.confirmed);
                let confirmed = g.status == Status::Ok && !jump;
                let mut tracks: Vec<Track> = g
                    .hypotheses
                    .into_iter()
                    .take(self.max_tracks)
                    .map(|h| Track {
                        deskewed: motion.is_some(),
                        ..Self::new_track(h, t_s, confirmed)
                    })
                    .collect();
                for mut old in self.tracks.drain(..).filter(|t| t.confirmed) {
                    old.coasting += 1;
                    if old.coasting <= self.max_coast {
                        tracks.push(old);
                    }
                }
                self.tracks = tracks;
            }
        }
        let mut fix = self.report(t_s, n_det, mode);
        fix.deskewed = motion.is_some() && fix.pose.is_some();
        fix
    }

    /// Drops hypotheses far behind the best in accumulated evidence, and in landmarks matched:
    /// one behind only by landmarks it predicts in view but never sees is kept, for a
    /// reflector missing from the room (fallen off, covered) shows just that of the right
    /// pose. In a symmetric room with one mapped reflector gone, the misses alone picked the
    /// mirror pose, 143 `ok` poses 4–6 m off.
    fn prune(&mut self) {
        self.tracks.sort_by(|a, b| b.cum.total_cmp(&a.cum));
        if let Some(best) = self.tracks.first().map(|t| t.cum) {
            let m = self.history_margin;
            let most_matched = self
                .tracks
                .iter()
                .map(|t| t.cum_matched)
                .fold(f64::NEG_INFINITY, f64::max);
            let before = self.tracks.len();
            self.tracks
                .retain(|t| t.cum >= best - m || t.cum_matched >= most_matched - m);
            if before > 1 && self.tracks.len() == 1 {
                self.tracks[0].confirmed = true;
            }
        }
        self.tracks.truncate(self.max_tracks);
    }

    fn report(&self, t_s: f64, n_det: usize, mode: &'static str) -> ScanFix {
        let Some(best) = self.tracks.first() else {
            return ScanFix::lost(t_s, n_det, 0, mode);
        };
        let ok = self.tracks.len() == 1 && best.confirmed && best.last.score >= 1.0;
        ScanFix {
            t_s,
            status: if ok { Status::Ok } else { Status::Ambiguous },
            pose: Some(best.pose),
            n_landmarks: best.last.matches.len(),
            n_detections: n_det,
            n_hypotheses: self.tracks.len(),
            score: best.last.score,
            mode,
            pose_cov: best.last.cov,
            deskewed: false,
            hypotheses: self
                .tracks
                .iter()
                .filter(|t| t.coasting == 0)
                .map(|t| t.last.clone())
                .collect(),
        }
    }
}

/// `dets` de-skewed for a sensor at `at` moving at `vel` (map frame: m/s, m/s, rad/s).
pub(crate) fn deskewed(dets: &[Detection], vel: [f64; 3], at: &Pose2) -> Vec<Detection> {
    let v = Rotation2::new(-at.theta_rad) * Vector2::new(vel[0], vel[1]);
    let mut out = dets.to_vec();
    for d in &mut out {
        d.deskew([v.x, v.y, vel[2]]);
    }
    out
}

fn same(a: &Pose2, b: &Pose2) -> bool {
    (a.position() - b.position()).norm() < 0.1
        && wrap_angle(a.theta_rad - b.theta_rad).abs() < 0.035
}
