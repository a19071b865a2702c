//! Association of detections with map landmarks and the pose: the source's
//! chained search, and the robust global search with negative evidence.

use nalgebra::{Matrix2, Matrix3, Point2, Rotation2, Vector2};
use odocal_core::{fit_helmert, fit_rigid, wrap_angle, Pose2};

use crate::pose_fit::{fit_pose_weighted, mahalanobis2, pose_information, Observation};
use crate::sweep::Sweep;
use crate::{extract_detections, Detection, Map, Scan, SensorConfig};

/// Settings of the localiser.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalizerConfig {
    /// The sensor model (noise, range, field of view).
    pub sensor: SensorConfig,
    /// Gates and margins are this many standard deviations wide.
    pub k_sigma: f64,
    /// Uncertainty of the surveyed landmark positions (1 sigma), metres: a margin of the
    /// association gates, and the pose fit's map variance unless the map states its own
    /// (`position_sigma_m`).
    pub map_sigma_m: f64,
    /// Minimum number of matched landmarks for a pose.
    pub min_matches: usize,
    /// Hypotheses whose scores are within this of the best one tie (ambiguous).
    pub ambiguity_margin: f64,
    /// Score penalty per landmark that should have been seen but was not.
    pub miss_weight: f64,
    /// A lone hypothesis needs at least this score to be reported `ok`.
    pub min_score_ok: f64,
    /// Detection pairs shorter than this are not used as anchors, metres.
    pub min_anchor_m: f64,
    /// A lone hypothesis is reported `ok` only if the odds that the search found it by
    /// coincidence stay below this ([`Localizer::chance_odds`]): few detections in a dense map
    /// are not proof of a pose.
    pub max_chance_ok: f64,
    /// A match whose residual at the weighted pose lies beyond this many standard deviations
    /// of its own covariance is dropped as a wrong association (infinite: every match the
    /// gates let in is kept).
    pub max_residual_sigmas: f64,
}

impl Default for LocalizerConfig {
    fn default() -> Self {
        LocalizerConfig {
            sensor: SensorConfig::default(),
            k_sigma: 4.0,
            map_sigma_m: 0.005,
            min_matches: 3,
            ambiguity_margin: 1.0,
            miss_weight: 1.0,
            min_score_ok: 1.0,
            min_anchor_m: 0.3,
            max_chance_ok: 1.0,
            max_residual_sigmas: 4.0,
        }
    }
}

/// One consistent pose hypothesis.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    /// Sensor pose in the map frame (maps sensor-frame points to map points).
    pub pose: Pose2,
    /// Matches as (detection index, landmark index).
    pub matches: Vec<(usize, usize)>,
    /// Landmarks that should have been detected from this pose but were not.
    pub n_missing: usize,
    /// Score: matches − miss_weight · missing.
    pub score: f64,
    /// RMS residual of the rigid fit, metres.
    pub rms_m: f64,
    /// Scale of the free-scale Helmert fit (consistency check, ≈ 1).
    pub helmert_scale: f64,
    /// Covariance of the pose (x, y, θ; m², m·rad, rad²) from the matched detections'
    /// covariances and the map's: the pose's Cramér–Rao bound, which the weighted fit reaches.
    pub cov: Option<Matrix3<f64>>,
    /// The matched detections as fitted, one per match: over a recording they tell a landmark
    /// moved since the map was made from noise. Empty for a search's unrefined hypotheses.
    pub(crate) observations: Vec<Observation>,
    /// Matches the fit left out as beyond their noise, (landmark index, observation): a
    /// landmark left out scan after scan, off the same way, was moved too far to be matched.
    pub(crate) outliers: Vec<(usize, Observation)>,
}

/// Outcome class of a localisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// One hypothesis, clearly better than any other.
    Ok,
    /// Several hypotheses tie (or the only one is weak).
    Ambiguous,
    /// No consistent hypothesis.
    Lost,
}

impl Status {
    /// The lower-case name used in files.
    pub fn as_str(&self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Ambiguous => "ambiguous",
            Status::Lost => "lost",
        }
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The result of localising one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Localization {
    /// ok / ambiguous / lost.
    pub status: Status,
    /// Consistent hypotheses, best first (scores within the ambiguity margin of the best).
    pub hypotheses: Vec<Hypothesis>,
    /// Number of detections in the scan.
    pub n_detections: usize,
}

impl Localization {
    /// The best hypothesis, if any.
    pub fn best(&self) -> Option<&Hypothesis> {
        self.hypotheses.first()
    }
}

/// Work counters of one search (for benchmarks and tuning).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SearchStats {
    /// Anchor detection pairs tried.
    pub anchors: usize,
    /// Landmark pairs proposed for the anchors.
    pub candidates: usize,
    /// Candidates refined into full hypotheses.
    pub refined: usize,
}

/// Localises scans against a map.
#[derive(Debug, Clone)]
pub struct Localizer {
    /// The map.
    pub map: Map,
    /// The settings.
    pub cfg: LocalizerConfig,
}

/// Two poses closer than this are the same hypothesis.
const SAME_POS_M: f64 = 0.1;
const SAME_HEADING_RAD: f64 = 0.035;
/// Largest association gate, metres (the grid answers radius queries up to 0.5 m quickly).
const MAX_GATE_M: f64 = 0.5;
/// A landmark this close to the edge of the field of view (or of the beams with a return) is
/// not expected to be detected: its strip may lie partly outside, and the pose's heading is
/// uncertain by about as much, radians (2°).
const VIEW_EDGE_MARGIN_RAD: f64 = 0.035;
/// Every this-many-th beam is checked against the mapped walls.
const FREE_SPACE_STRIDE: usize = 8;

fn same_pose(a: &Pose2, b: &Pose2) -> bool {
    (a.position() - b.position()).norm() < SAME_POS_M
        && wrap_angle(a.theta_rad - b.theta_rad).abs() < SAME_HEADING_RAD
}

impl Localizer {
    /// A localiser for `map` with settings `cfg`.
    pub fn new(map: Map, cfg: LocalizerConfig) -> Localizer {
        Localizer { map, cfg }
    }

    /// Detections of a scan with this map's reflector width.
    pub fn detections(&self, scan: &Scan) -> Vec<Detection> {
        extract_detections(scan, &self.cfg.sensor, self.map.reflector_width_m)
    }

    /// Variance of a detection centre plus the map's, m² (isotropic bound).
    fn point_var(&self, d: &Detection) -> f64 {
        d.var_radial_m2 + d.var_tangential_m2 + self.cfg.map_sigma_m.powi(2)
    }

    /// Global localisation without a prior (all consistent hypotheses).
    pub fn global(&self, scan: &Scan, dets: &[Detection]) -> Localization {
        self.global_impl(scan, dets, false).0
    }

    /// Global localisation with work counters.
    pub fn global_with_stats(
        &self,
        scan: &Scan,
        dets: &[Detection],
    ) -> (Localization, SearchStats) {
        self.global_impl(scan, dets, false)
    }

    /// Baseline for benchmarks: the same hypotheses, but landmark pairs are
    /// found by comparing every ordered pair's distance (no sorted edges, no binary search).
    pub fn global_brute_force(&self, scan: &Scan, dets: &[Detection]) -> Localization {
        self.global_impl(scan, dets, true).0
    }

    fn global_impl(
        &self,
        scan: &Scan,
        dets: &[Detection],
        brute: bool,
    ) -> (Localization, SearchStats) {
        let cfg = &self.cfg;
        let n = dets.len();
        let mut stats = SearchStats::default();
        let mut hyps: Vec<Hypothesis> = Vec::new();
        if n < cfg.min_matches {
            return (self.finish(hyps, dets, 0), stats);
        }
        // Anchors are taken from a growing prefix of detections, closest (most precise) first.
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| dets[a].range_m.total_cmp(&dets[b].range_m));
        let var: Vec<f64> = dets.iter().map(|d| self.point_var(d)).collect();
        let mut best_score = f64::NEG_INFINITY;
        let mut s_min = cfg.min_matches;
        let mut gates = vec![0.0; n];
        let max_pair_m = 2.0 * cfg.sensor.max_range_m;
        for p in 1..n {
            for &i in &order[..p] {
                let j = order[p];
                let dij = dets[j].point - dets[i].point;
                let d = dij.norm();
                if d < cfg.min_anchor_m {
                    continue;
                }
                let u = dij / d;
                let sd = (u.dot(&(dets[i].cov() * u))
                    + u.dot(&(dets[j].cov() * u))
                    + 2.0 * cfg.map_sigma_m.powi(2))
                .sqrt();
                let margin = cfg.k_sigma * sd;
                if d - margin > max_pair_m {
                    continue;
                }
                stats.anchors += 1;
                // Association gates for the other detections under a pose from this anchor pair.
                let mid = Point2::from((dets[i].point.coords + dets[j].point.coords) * 0.5);
                let s_theta2 = (var[i] + var[j]) / (d * d);
                let s_mid2 = 0.5 * (var[i] + var[j]) * 0.5;
                for k in 0..n {
                    let dk2 = (dets[k].point - mid).norm_squared();
                    gates[k] =
                        (cfg.k_sigma * (var[k] + s_mid2 + dk2 * s_theta2).sqrt()).min(MAX_GATE_M);
                }
                let a_det = dij.y.atan2(dij.x);
                let try_pair = |a: usize,
                                b: usize,
                                hyps: &mut Vec<Hypothesis>,
                                stats: &mut SearchStats| {
                    stats.candidates += 1;
                    let ma = self.map.position(a);
                    let mb = self.map.position(b);
                    let mab = mb - ma;
                    let theta = mab.y.atan2(mab.x) - a_det;
                    let rot = Rotation2::new(theta);
                    let t = Point2::from((ma.coords + mb.coords) * 0.5) - rot * mid.coords;
                    let lm = &self.map.landmarks;
                    if !lm[a].visible_from(&t, -0.1, -0.1) || !lm[b].visible_from(&t, -0.1, -0.1) {
                        return;
                    }
                    let pose = Pose2::new(t.x, t.y, theta);
                    // Already explained: a hypothesis that matched this anchor pair the same way.
                    if hyps
                        .iter()
                        .any(|h| h.matches.contains(&(i, a)) && h.matches.contains(&(j, b)))
                    {
                        return;
                    }
                    let mut count = 2usize;
                    let mut remaining = n - 2;
                    for &k in &order {
                        if k == i || k == j {
                            continue;
                        }
                        remaining -= 1;
                        let q = rot * dets[k].point + t.coords;
                        let hit = if brute {
                            let g2 = gates[k] * gates[k];
                            (0..lm.len()).any(|l| {
                                l != a && l != b && (lm[l].position - q).norm_squared() <= g2
                            })
                        } else {
                            self.map
                                .nearest_within(&q, gates[k], |l| l != a && l != b)
                                .is_some()
                        };
                        if hit {
                            count += 1;
                        } else if count + remaining < s_min {
                            return;
                        }
                    }
                    if count < s_min {
                        return;
                    }
                    stats.refined += 1;
                    if let Some(h) = self.refine(scan, dets, pose, gates.as_slice()) {
                        match hyps.iter_mut().find(|o| same_pose(&o.pose, &h.pose)) {
                            Some(o) if o.score >= h.score => {}
                            Some(o) => *o = h,
                            None => hyps.push(h),
                        }
                    }
                };
                if brute {
                    let nl = self.map.len();
                    for a in 0..nl {
                        for b in 0..nl {
                            if a != b
                                && ((self.map.position(b) - self.map.position(a)).norm() - d).abs()
                                    <= margin
                            {
                                try_pair(a, b, &mut hyps, &mut stats);
                            }
                        }
                    }
                } else {
                    let lo = self.map.pair_dist.partition_point(|&x| x < d - margin);
                    let hi = self.map.pair_dist.partition_point(|&x| x <= d + margin);
                    for e in lo..hi {
                        let (a, b) = self.map.pair_ab[e];
                        try_pair(a as usize, b as usize, &mut hyps, &mut stats);
                        try_pair(b as usize, a as usize, &mut hyps, &mut stats);
                    }
                }
                for h in &hyps {
                    if h.score > best_score {
                        best_score = h.score;
                    }
                }
                // Competitors must reach best − margin, so they need at least that many matches.
                let need = (best_score - cfg.ambiguity_margin - 1e-9).ceil();
                if need.is_finite() && need > s_min as f64 {
                    s_min = need as usize;
                }
            }
            // Every hypothesis with ≥ s_min matched detections has two of them
            // among the first p+1 detections once p+1 ≥ n − s_min + 2.
            if p + 1 + s_min >= n + 2 {
                break;
            }
        }
        (self.finish(hyps, dets, stats.candidates), stats)
    }

    /// The expected number of hypotheses at least as well supported as `h` that the global
    /// search finds by coincidence (an a-contrario count): the `candidates` landmark pairs it
    /// tried for anchors, times the ways of choosing `h`'s other matched detections, times the
    /// chance that each lands in some landmark's gate at a wrong pose (the local landmark
    /// density around the pose × the gate's area). Three detections in a 200-landmark map
    /// match somewhere about half the time; seven almost never do.
    pub fn chance_hypotheses(&self, h: &Hypothesis, dets: &[Detection], candidates: usize) -> f64 {
        let r = self.cfg.sensor.max_range_m;
        let s = h.pose.position();
        let near = self
            .map
            .landmarks
            .iter()
            .filter(|l| (l.position - s).norm() <= r)
            .count();
        let density = near as f64 / (std::f64::consts::PI * r * r);
        let mut p: Vec<f64> = h
            .matches
            .iter()
            .map(|&(k, _)| {
                (density * std::f64::consts::PI * self.tight_gate(&dets[k]).powi(2)).min(1.0)
            })
            .collect();
        // The two anchors are given by the candidate pair, the others must fall in by chance.
        p.sort_by(|a, b| b.total_cmp(a));
        let others = p.len().saturating_sub(2);
        let ways = binomial(dets.len().saturating_sub(2), others);
        candidates as f64 * ways * p.iter().skip(2).product::<f64>()
    }

    /// The odds that `h` is a coincidence rather than the pose: [`Self::chance_hypotheses`],
    /// doubled for every landmark the pose says is in view but the scan did not detect (a
    /// landmark in view is missed at most half the time, a conservative figure: the scanner
    /// simulated by `odocal synth lrf` misses 11 %).
    pub fn chance_odds(&self, h: &Hypothesis, dets: &[Detection], candidates: usize) -> f64 {
        self.chance_hypotheses(h, dets, candidates) * 2f64.powi(h.n_missing.min(60) as i32)
    }

    /// The association gate once the pose is known to a few millimetres, metres.
    fn tight_gate(&self, d: &Detection) -> f64 {
        self.cfg.k_sigma * (self.point_var(d) + 1e-4 + (d.range_m * 0.002).powi(2)).sqrt()
    }

    /// Sorts hypotheses, keeps those tying with the best and decides the status: `ok` needs a
    /// lone hypothesis with enough score that is not explained by coincidence.
    fn finish(
        &self,
        mut hyps: Vec<Hypothesis>,
        dets: &[Detection],
        candidates: usize,
    ) -> Localization {
        let n_detections = dets.len();
        hyps.sort_by(|a, b| {
            b.score
                .total_cmp(&a.score)
                .then(a.rms_m.total_cmp(&b.rms_m))
        });
        let status = match hyps.first() {
            None => Status::Lost,
            Some(best) => {
                let floor = best.score - self.cfg.ambiguity_margin;
                let best_score = best.score;
                let chance = self.chance_odds(best, dets, candidates.max(1));
                hyps.retain(|h| h.score >= floor);
                if hyps.len() == 1
                    && best_score >= self.cfg.min_score_ok
                    && chance <= self.cfg.max_chance_ok
                {
                    Status::Ok
                } else {
                    Status::Ambiguous
                }
            }
        };
        Localization {
            status,
            hypotheses: hyps,
            n_detections,
        }
    }

    /// Tracking mode: matches detections near a predicted pose with the
    /// given 1-sigma position and heading uncertainty.
    pub fn track(
        &self,
        scan: &Scan,
        dets: &[Detection],
        predicted: Pose2,
        pos_sigma_m: f64,
        heading_sigma_rad: f64,
    ) -> Option<Hypothesis> {
        let gates: Vec<f64> = dets
            .iter()
            .map(|d| {
                let v = self.point_var(d)
                    + pos_sigma_m.powi(2)
                    + (d.range_m * heading_sigma_rad).powi(2);
                (self.cfg.k_sigma * v.sqrt()).min(MAX_GATE_M)
            })
            .collect();
        let h = self.refine(scan, dets, predicted, &gates)?;
        // Evidence must not be strongly against the pose.
        (h.n_missing <= h.matches.len()).then_some(h)
    }

    /// Associates with `gates` around `guess`, then refits with tight gates;
    /// checks visibility, Helmert scale and negative evidence.
    pub(crate) fn refine(
        &self,
        scan: &Scan,
        dets: &[Detection],
        guess: Pose2,
        gates: &[f64],
    ) -> Option<Hypothesis> {
        let cfg = &self.cfg;
        let mut pose = guess;
        let mut matches: Vec<(usize, usize)> = Vec::with_capacity(dets.len());
        let mut cand: Vec<(f64, usize, usize)> = Vec::with_capacity(dets.len());
        let mut taken = vec![false; self.map.len()];
        let mut fit_rms = 0.0;
        for iter in 0..3 {
            let iso = pose.isometry();
            let s = pose.position();
            cand.clear();
            for (k, d) in dets.iter().enumerate() {
                let gate = if iter == 0 {
                    gates[k]
                } else {
                    self.tight_gate(d)
                };
                let q = iso * d.point;
                if let Some((l, dist)) = self.map.nearest_within(&q, gate, |l| {
                    let lm = &self.map.landmarks[l];
                    lm.visible_from(&s, -0.1, -0.1) && !self.map.occluded(&s, &lm.position, 0.05)
                }) {
                    cand.push((dist, k, l));
                }
            }
            cand.sort_by(|a, b| a.0.total_cmp(&b.0));
            taken.iter_mut().for_each(|t| *t = false);
            matches.clear();
            for &(_, k, l) in &cand {
                if !taken[l] {
                    taken[l] = true;
                    matches.push((k, l));
                }
            }
            if matches.len() < cfg.min_matches {
                return None;
            }
            let src: Vec<Point2<f64>> = matches.iter().map(|&(k, _)| dets[k].point).collect();
            let dst: Vec<Point2<f64>> =
                matches.iter().map(|&(_, l)| self.map.position(l)).collect();
            let fit = fit_rigid(&src, &dst).ok()?;
            pose = fit.pose;
            fit_rms = fit.rms;
        }
        // Free-scale Helmert as a consistency check: the scale must be 1 within noise.
        let src: Vec<Point2<f64>> = matches.iter().map(|&(k, _)| dets[k].point).collect();
        let dst: Vec<Point2<f64>> = matches.iter().map(|&(_, l)| self.map.position(l)).collect();
        let helmert = fit_helmert(&src, &dst).ok()?;
        let mean = src.iter().map(|p| p.coords).sum::<Vector2<f64>>() / src.len() as f64;
        let spread2: f64 = src.iter().map(|p| (p.coords - mean).norm_squared()).sum();
        let sp = (matches
            .iter()
            .map(|&(k, _)| self.point_var(&dets[k]))
            .sum::<f64>()
            / matches.len() as f64)
            .sqrt();
        let scale_tol = cfg.k_sigma * sp / spread2.sqrt() + 1e-3;
        // The residuals must be those of noise, and the scale 1 within noise.
        if fit_rms > 2.0 * sp + 0.005 || (helmert.scale - 1.0).abs() > scale_tol {
            return None;
        }
        // The pose: every detection weighted by its covariance, from the rigid fit (which
        // weighs all alike and serves the association and the checks above).
        let gated = matches.clone();
        let (pose, cov) = self.fit_consistent(dets, &mut matches, pose)?;
        let left_out: Vec<(usize, usize)> =
            gated.into_iter().filter(|m| !matches.contains(m)).collect();
        let outliers = left_out
            .iter()
            .map(|m| m.1)
            .zip(self.observations(dets, &left_out, &pose))
            .collect();
        for t in taken.iter_mut() {
            *t = false;
        }
        for &(_, l) in &matches {
            taken[l] = true;
        }
        if self.free_space_violations(scan, &pose)
            > 2 + scan.ranges_m.len() / FREE_SPACE_STRIDE / 30
        {
            return None;
        }
        let n_missing = self.count_missing(scan, &pose, &taken);
        let score = matches.len() as f64 - cfg.miss_weight * n_missing as f64;
        let observations = self.observations(dets, &matches, &pose);
        Some(Hypothesis {
            pose,
            matches,
            n_missing,
            score,
            rms_m: fit_rms,
            helmert_scale: helmert.scale,
            cov: Some(cov),
            observations,
            outliers,
        })
    }

    /// The observations of `matches` (detection, landmark) for a pose near `guess`: each
    /// detection's strip centre and covariance ([`Detection::strip_centre`], with the strip's
    /// orientation from the map turned into the sensor frame) plus the map's variance.
    fn observations(
        &self,
        dets: &[Detection],
        matches: &[(usize, usize)],
        guess: &Pose2,
    ) -> Vec<Observation> {
        let sigma = self.map.position_sigma_m.unwrap_or(self.cfg.map_sigma_m);
        let to_sensor = Rotation2::new(-guess.theta_rad);
        matches
            .iter()
            .map(|&(k, l)| {
                let lm = &self.map.landmarks[l];
                let normal = lm.facing.map(|f| to_sensor * f);
                let (centre, cov) = dets[k].strip_centre(
                    normal,
                    lm.half_fov_rad,
                    self.map.reflector_width_m,
                    &self.cfg.sensor,
                );
                Observation {
                    sensor: centre,
                    landmark: lm.position,
                    cov: cov + Matrix2::identity() * sigma * sigma,
                }
            })
            .collect()
    }

    /// The weighted fit of `matches` ([`Self::fit_worst`]) with the matches it cannot explain
    /// dropped: while some residual lies beyond `max_residual_sigmas` standard deviations of its own
    /// covariance, the match whose removal leaves the most consistent fit goes (a wrong match
    /// pulls the fit towards itself, so the worst residual may be a right match's). The rigid
    /// fit's gates and RMS check bound every detection by its loosest error, which for a
    /// reflector hit by one beam far away (a beam spacing along the strip, 7 cm at 1.4° and
    /// 3 m) lets a glint matched to a landmark 18 cm off pass; the weighted fit then trusts the
    /// other detections' few millimetres and puts the pose between them, 14 cm off with a σ of
    /// 9 mm. None when fewer than `min_matches` would remain.
    fn fit_consistent(
        &self,
        dets: &[Detection],
        matches: &mut Vec<(usize, usize)>,
        guess: Pose2,
    ) -> Option<(Pose2, Matrix3<f64>)> {
        let limit = self.cfg.max_residual_sigmas.powi(2);
        loop {
            let (pose, cov, worst) = self.fit_worst(dets, matches, guess)?;
            if worst <= limit {
                return Some((pose, cov));
            }
            if matches.len() <= self.cfg.min_matches {
                return None;
            }
            let drop = (0..matches.len())
                .filter_map(|k| {
                    let mut rest = matches.clone();
                    rest.remove(k);
                    Some((self.fit_worst(dets, &rest, guess)?.2, k))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))?;
            matches.remove(drop.1);
        }
    }

    /// The pose from detections matched to landmarks, (detection index, landmark index),
    /// starting from `guess` (a rigid fit of the same matches, say): the weighted least-squares
    /// fit with every detection's covariance, the pose's covariance (x, y, θ; m², m·rad, rad²),
    /// which is its Cramér–Rao bound, and the largest squared Mahalanobis distance of a match's
    /// residual at that pose. None when the matches do not fix a pose.
    fn fit_worst(
        &self,
        dets: &[Detection],
        matches: &[(usize, usize)],
        guess: Pose2,
    ) -> Option<(Pose2, Matrix3<f64>, f64)> {
        let obs = self.observations(dets, matches, &guess);
        let (pose, cov) = fit_pose_weighted(guess, &obs)?;
        let mut worst = 0.0f64;
        for o in &obs {
            worst = worst.max(mahalanobis2(&pose, o)?);
        }
        Some((pose, cov, worst))
    }

    /// Beams that contradict the mapped walls from `pose`: a return well beyond the nearest
    /// wall along the beam (seen through a wall). A beam without a return (range 0, below the
    /// minimum range, or infinite) says nothing about free space: a dark or glass surface, or
    /// a dropout, returns nothing from a wall in range, so it is no evidence against the pose.
    /// Every `FREE_SPACE_STRIDE`-th beam is checked; 0 when the map has no walls.
    pub fn free_space_violations(&self, scan: &Scan, pose: &Pose2) -> usize {
        if self.map.walls.is_empty() {
            return 0;
        }
        let sens = &self.cfg.sensor;
        let s = pose.position();
        let tol = 0.2 + 3.0 * sens.sigma_range_m;
        // From the seam, so that a full turn has the same beams checked wherever its array starts.
        let sweep = Sweep::new(scan, sens);
        let mut bad = 0;
        for k in (0..sweep.len()).step_by(FREE_SPACE_STRIDE) {
            let a = pose.theta_rad + sweep.angle_rad(k);
            let dir = Vector2::new(a.cos(), a.sin());
            let Some(t) = self.map.ray_to_wall(&s, &dir) else {
                continue;
            };
            let r = sweep.range_m(k);
            if r >= sens.min_range_m && r.is_finite() && r > t + tol {
                bad += 1;
            }
        }
        bad
    }

    /// Negative evidence: landmarks that should have been detected from
    /// `pose` — in range and field of view with margins, in front of their
    /// reflecting surface, not behind a mapped wall, and with the scan showing
    /// free space up to them — but are not among the `matched` ones. Only a beam that returned
    /// from beyond a landmark shows it missing: beams without a return there (glass, a dark
    /// surface, a sector the robot's body masks) say nothing, as in
    /// [`Localizer::free_space_violations`], and the field of view ends at the first and last
    /// beams with a return. Counted, the no-return rear of a 360° scanner made 42 of 100 scans
    /// ambiguous.
    pub fn count_missing(&self, scan: &Scan, pose: &Pose2, matched: &[bool]) -> usize {
        let mut n = 0;
        self.for_each_missing(scan, pose, matched, |_| n += 1);
        n
    }

    /// Calls `f` with every landmark counted by [`Localizer::count_missing`].
    pub fn for_each_missing(
        &self,
        scan: &Scan,
        pose: &Pose2,
        matched: &[bool],
        mut f: impl FnMut(usize),
    ) {
        let sens = &self.cfg.sensor;
        let s = pose.position();
        let inv = pose.isometry().inverse();
        let half_fov = 0.5 * sens.fov_rad - VIEW_EDGE_MARGIN_RAD;
        let step = scan.step_rad().abs().max(1e-6);
        let sweep = Sweep::new(scan, sens);
        // The edges of the beams with a return are edges of the field of view; a full turn
        // with a return all round has none.
        let Some((first, last)) = sweep.returning_span() else {
            return;
        };
        let seen = (sweep.angle_rad(first) + VIEW_EDGE_MARGIN_RAD)
            ..=(sweep.angle_rad(last) - VIEW_EDGE_MARGIN_RAD);
        self.map.for_each_within(&s, sens.max_range_m - 0.15, |l| {
            if matched[l] {
                return;
            }
            let lm = &self.map.landmarks[l];
            let p = inv * lm.position;
            let rho = p.coords.norm();
            let beta = p.y.atan2(p.x);
            if rho < sens.min_range_m + 0.1
                || beta.abs() > half_fov
                || !(sweep.is_closed() || seen.contains(&sweep.unwrap(beta)))
            {
                return;
            }
            if !lm.visible_from(&s, 0.09, 0.05) || self.map.occluded(&s, &lm.position, 0.05) {
                return;
            }
            let Some(c) = sweep.beam_at(beta) else {
                return;
            };
            let half = ((0.5 * self.map.reflector_width_m / rho) / step).ceil() as isize + 1;
            let mut seen_through = false;
            for k in (c as isize - half..=c as isize + half).filter_map(|k| sweep.neighbour(k)) {
                let r = sweep.range_m(k);
                if r < sens.min_range_m {
                    continue;
                }
                if r < rho - 0.15 {
                    return; // something unmapped in front of it
                }
                if sweep.intensity(k) >= sens.intensity_min && (r - rho).abs() < 0.3 {
                    return; // a reflective return is there (detection rejected or not matched)
                }
                seen_through = true;
            }
            if seen_through {
                f(l);
            }
        });
    }

    /// The source's search, faithfully: for every map landmark as L1, find
    /// landmarks at distance |L1L2| by binary search in its sorted edges, then
    /// chain: L(k+1) at distance |LkL(k+1)| from the match of Lk and at the
    /// measured angle relative to the previous segment, until all n
    /// detections are matched. Succeeds only if every detection is a mapped
    /// landmark. The pose is the Helmert transform, as in the source.
    pub fn source_search(&self, dets: &[Detection]) -> Vec<Hypothesis> {
        let n = dets.len();
        let mut out: Vec<Hypothesis> = Vec::new();
        if n < 2 {
            return out;
        }
        let cfg = &self.cfg;
        let seg: Vec<Vector2<f64>> = (0..n - 1)
            .map(|k| dets[k + 1].point - dets[k].point)
            .collect();
        let len: Vec<f64> = seg.iter().map(|v| v.norm()).collect();
        let sd: Vec<f64> = (0..n - 1)
            .map(|k| (self.point_var(&dets[k]) + self.point_var(&dets[k + 1])).sqrt())
            .collect();
        let turn: Vec<f64> = (0..n.saturating_sub(2))
            .map(|k| wrap_angle(seg[k + 1].y.atan2(seg[k + 1].x) - seg[k].y.atan2(seg[k].x)))
            .collect();
        let mut chain: Vec<usize> = Vec::with_capacity(n);
        for a in 0..self.map.len() {
            let r = self.map.edges_in(
                a,
                len[0] - cfg.k_sigma * sd[0],
                len[0] + cfg.k_sigma * sd[0],
            );
            for e in r {
                chain.clear();
                chain.push(a);
                chain.push(self.map.edge_to[e] as usize);
                self.source_chain(
                    dets,
                    &len,
                    &sd,
                    &turn,
                    self.map.edge_dir[e],
                    &mut chain,
                    &mut out,
                );
            }
        }
        out
    }

    #[allow(clippy::too_many_arguments)]
    fn source_chain(
        &self,
        dets: &[Detection],
        len: &[f64],
        sd: &[f64],
        turn: &[f64],
        prev_dir: f64,
        chain: &mut Vec<usize>,
        out: &mut Vec<Hypothesis>,
    ) {
        let k = chain.len() - 1; // detection index of the chain's last landmark
        if chain.len() == dets.len() {
            let src: Vec<Point2<f64>> = dets.iter().map(|d| d.point).collect();
            let dst: Vec<Point2<f64>> = chain.iter().map(|&l| self.map.position(l)).collect();
            if let Ok(h) = fit_helmert(&src, &dst) {
                if out.iter().all(|o| !same_pose(&o.pose, &h.pose)) {
                    let matches: Vec<(usize, usize)> = chain.iter().copied().enumerate().collect();
                    let obs = self.observations(dets, &matches, &h.pose);
                    let cov = pose_information(&h.pose, &obs).and_then(|i| i.try_inverse());
                    out.push(Hypothesis {
                        pose: h.pose,
                        matches,
                        n_missing: 0,
                        score: chain.len() as f64,
                        rms_m: h.rms,
                        helmert_scale: h.scale,
                        cov,
                        observations: Vec::new(),
                        outliers: Vec::new(),
                    });
                }
            }
            return;
        }
        let cur = chain[k];
        let m = self.cfg.k_sigma * sd[k];
        let angle_tol = self.cfg.k_sigma * (sd[k - 1] / len[k - 1] + sd[k] / len[k]);
        for e in self.map.edges_in(cur, len[k] - m, len[k] + m) {
            let next = self.map.edge_to[e] as usize;
            if chain.contains(&next) {
                continue;
            }
            let dir = self.map.edge_dir[e];
            if wrap_angle(dir - prev_dir - turn[k - 1]).abs() > angle_tol {
                continue;
            }
            chain.push(next);
            self.source_chain(dets, len, sd, turn, dir, chain, out);
            chain.pop();
        }
    }
}

/// n choose k, as a float.
fn binomial(n: usize, k: usize) -> f64 {
    (0..k.min(n)).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}
