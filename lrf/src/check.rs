//! Map check: sub-configurations of landmarks that are congruent (or
//! mirror images) within the sensor's accuracy, i.e. places the sensor could
//! confuse.

use nalgebra::{Point2, Rotation2, Vector2};
use odocal_core::{wrap_angle, Pose2};

use crate::LrfError;
use crate::Map;

/// How two sub-configurations relate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AmbiguityKind {
    /// A rigid motion maps one onto the other: truly ambiguous for any matcher.
    Congruent,
    /// A reflection maps one onto the other: ambiguous for distance-only
    /// matching; a rigid matcher (no reflection) tells them apart.
    Mirror,
}

/// One ambiguous sub-configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Ambiguity {
    /// Congruent or mirror image.
    pub kind: AmbiguityKind,
    /// Landmark ids of the first configuration.
    pub from_ids: Vec<u32>,
    /// Landmark ids they map onto, in the same order.
    pub to_ids: Vec<u32>,
    /// The rigid motion (for mirror images: applied after reflecting y) mapping `from` onto `to`.
    pub transform: Pose2,
}

impl Ambiguity {
    /// Number of landmarks in the configuration.
    pub fn size(&self) -> usize {
        self.from_ids.len()
    }
}

/// Finds landmark sets of at least `min_size` (≥ 3) landmarks, all within
/// `radius_m` of their first pair's midpoint (seen together), that another
/// set matches within `tol_m` by a rigid motion or a reflection, with
/// consistent reflector orientations; not when a landmark of the other set is itself within
/// that radius and nothing lies where the motion takes it (seen with the set, it tells the
/// two places apart). Largest first.
pub fn find_ambiguities(map: &Map, tol_m: f64, radius_m: f64, min_size: usize) -> Vec<Ambiguity> {
    find_ambiguities_within(map, tol_m, radius_m, min_size, usize::MAX).0
}

/// `lrf check-map`'s tolerance unless told: two configurations match if every landmark is
/// within this, metres.
pub const DEFAULT_TOLERANCE_M: f64 = 0.03;

/// Whether scans may fit `map` in several places for its layout alone: it holds congruent
/// configurations of 3 or more landmarks seen together within `max_range_m` (at
/// [`DEFAULT_TOLERANCE_M`]), or so many candidates that the search gave up, as
/// `lrf check-map` would report.
pub fn layout_repeats(map: &Map, max_range_m: f64) -> bool {
    let (found, complete) =
        find_ambiguities_within(map, DEFAULT_TOLERANCE_M, max_range_m, 3, CHECK_BUDGET);
    !complete || found.iter().any(|a| a.kind == AmbiguityKind::Congruent)
}

/// The most candidate matches [`check_map_report`] tries: a map of a building's reflectors
/// needs far fewer; a regular lattice needs millions, and is ambiguous anyway.
pub const CHECK_BUDGET: usize = 200_000;

/// [`find_ambiguities`] that stops after `budget` candidate matches; the flag says whether
/// the search was complete.
pub fn find_ambiguities_within(
    map: &Map,
    tol_m: f64,
    radius_m: f64,
    min_size: usize,
    budget: usize,
) -> (Vec<Ambiguity>, bool) {
    let mut trials = 0usize;
    let n = map.len();
    let mut found: Vec<Ambiguity> = Vec::new();
    let min_size = min_size.max(3);
    let mut used = vec![false; n];
    for e1 in 0..map.pair_dist.len() {
        let d = map.pair_dist[e1];
        if d > radius_m {
            break;
        }
        let hi = map.pair_dist.partition_point(|&x| x <= d + tol_m);
        for e2 in e1..hi {
            let (a, b) = map.pair_ab[e1];
            let (c0, d0) = map.pair_ab[e2];
            for (c, dd) in [(c0, d0), (d0, c0)] {
                for kind in [AmbiguityKind::Congruent, AmbiguityKind::Mirror] {
                    let (a, b, c, dd) = (a as usize, b as usize, c as usize, dd as usize);
                    let refl = |p: Point2<f64>| match kind {
                        AmbiguityKind::Congruent => p,
                        AmbiguityKind::Mirror => Point2::new(p.x, -p.y),
                    };
                    let (pa, pb) = (refl(map.position(a)), refl(map.position(b)));
                    let (pc, pd) = (map.position(c), map.position(dd));
                    let u = pb - pa;
                    let v = pd - pc;
                    let theta = v.y.atan2(v.x) - u.y.atan2(u.x);
                    let rot = Rotation2::new(theta);
                    let t = pc.coords - rot * pa.coords;
                    let tr = |p: Point2<f64>| Point2::from(rot * refl(p).coords + t);
                    let is_identity = kind == AmbiguityKind::Congruent && (c, dd) == (a, b);
                    if is_identity {
                        continue;
                    }
                    trials += 1;
                    if trials > budget {
                        return (sorted(found), false);
                    }
                    let mid = Point2::from((map.position(a).coords + map.position(b).coords) * 0.5);
                    let mut from = Vec::new();
                    let mut to = Vec::new();
                    used.iter_mut().for_each(|x| *x = false);
                    let mut ok = true;
                    map.for_each_within(&mid, radius_m, |i| {
                        let q = tr(map.position(i));
                        if let Some((j, _)) = map.nearest_within(&q, tol_m, |j| !used[j]) {
                            if facing_matches(map, i, j, theta, kind) {
                                used[j] = true;
                                from.push(i);
                                to.push(j);
                            } else if i == a || i == b {
                                ok = false;
                            }
                        }
                    });
                    if !ok || from.len() < min_size || from == to {
                        continue;
                    }
                    // A motion onto landmarks in view with the configuration itself (reflectors
                    // in pairs 15 cm apart, moved onto their twins) confuses nothing: a scan
                    // sees those landmarks too, and nothing lies where the motion takes them.
                    let overlaps = to
                        .iter()
                        .any(|&j| !from.contains(&j) && (map.position(j) - mid).norm() <= radius_m);
                    if overlaps {
                        continue;
                    }
                    let transform = Pose2::new(t.x, t.y, wrap_angle(theta));
                    let same = found.iter_mut().find(|f| {
                        f.kind == kind
                            && (f.transform.position() - transform.position()).norm() < 3.0 * tol_m
                            && wrap_angle(f.transform.theta_rad - transform.theta_rad).abs() < 0.02
                    });
                    let ids =
                        |v: &[usize]| v.iter().map(|&k| map.landmarks[k].id).collect::<Vec<u32>>();
                    let amb = Ambiguity {
                        kind,
                        from_ids: ids(&from),
                        to_ids: ids(&to),
                        transform,
                    };
                    match same {
                        Some(f) if f.size() >= amb.size() => {}
                        Some(f) => *f = amb,
                        None => found.push(amb),
                    }
                }
            }
        }
    }
    (sorted(found), true)
}

/// Largest first, congruent before mirror.
fn sorted(mut found: Vec<Ambiguity>) -> Vec<Ambiguity> {
    found.sort_by(|a, b| {
        b.size()
            .cmp(&a.size())
            .then((a.kind as u8).cmp(&(b.kind as u8)))
    });
    found
}

fn facing_matches(map: &Map, i: usize, j: usize, theta: f64, kind: AmbiguityKind) -> bool {
    match (map.landmarks[i].facing, map.landmarks[j].facing) {
        (None, None) => true,
        (Some(fi), Some(fj)) => {
            let fi = match kind {
                AmbiguityKind::Congruent => fi,
                AmbiguityKind::Mirror => Vector2::new(fi.x, -fi.y),
            };
            let g = Rotation2::new(theta) * fi;
            g.dot(&fj) > 0.5f64.cos()
        }
        _ => false,
    }
}

/// The check of a map as `odocal lrf check-map` prints it: the map, the counts, up to ten
/// ambiguous configurations, and the verdict. Refuses settings without sense first.
pub fn check_map_report(
    map: &Map,
    name: &str,
    tolerance_m: f64,
    max_range_m: f64,
    min_size: usize,
) -> Result<Vec<String>, LrfError> {
    if !(tolerance_m > 0.0 && tolerance_m <= 0.5) {
        return Err(LrfError::Config(format!(
            "--tolerance-m {tolerance_m} must be in (0, 0.5] metres"
        )));
    }
    if !(max_range_m.is_finite() && max_range_m > 0.0 && max_range_m <= 1000.0) {
        return Err(LrfError::Config(format!(
            "--max-range-m {max_range_m}: need a range in (0, 1000] metres"
        )));
    }
    if min_size < 3 {
        return Err(LrfError::Config(format!(
            "--min-size {min_size}: a pose needs at least 3 landmarks"
        )));
    }
    let (amb, complete) =
        find_ambiguities_within(map, tolerance_m, max_range_m, min_size, CHECK_BUDGET);
    let congruent_found = amb.iter().any(|x| x.kind == AmbiguityKind::Congruent);
    // A search that stopped with congruent configurations in hand has its verdict: more
    // of them would not make the layout less ambiguous. Only one that stopped with none
    // found cannot judge the map.
    if !complete && !congruent_found {
        return Err(LrfError::Config(format!(
            "{name}: the ambiguity search stopped after {CHECK_BUDGET} candidate matches with {} ambiguous configurations found: the layout repeats itself within {tolerance_m} m (a regular lattice, or so many reflectors that groups of them match others by chance) and a scan seeing only such a group cannot be placed without motion; break the symmetry by moving some reflectors, or judge it with a smaller --tolerance-m if the reflectors are surveyed more finely",
            amb.len()
        )));
    }
    let of = |k: AmbiguityKind| amb.iter().filter(move |x| x.kind == k);
    let (congruent, mirror) = (
        of(AmbiguityKind::Congruent).count(),
        of(AmbiguityKind::Mirror).count(),
    );
    let at_least = if complete { "" } else { "at least " };
    let mut out = vec![
        format!(
            "{name}: {} landmarks, {} walls; tolerance {tolerance_m:.3} m, range {max_range_m:.1} m",
            map.len(),
            map.walls.len()
        ),
        format!("congruent sub-configurations (ambiguous for any matcher): {at_least}{congruent}; mirror images (ambiguous for distance-only matching): {at_least}{mirror}"),
    ];
    if !complete {
        out.push(format!(
            "the search stopped after {CHECK_BUDGET} candidate matches: the counts are those found by then, the largest configurations may be missing"
        ));
    }
    for x in of(AmbiguityKind::Congruent)
        .chain(of(AmbiguityKind::Mirror))
        .take(10)
    {
        out.push(format!(
            "  {:<9} {} landmarks: ids {:?} ~ ids {:?} (moved {:.2} m, turned {:.1} deg)",
            match x.kind {
                AmbiguityKind::Congruent => "congruent",
                AmbiguityKind::Mirror => "mirror",
            },
            x.size(),
            x.from_ids,
            x.to_ids,
            x.transform.position().coords.norm(),
            x.transform.theta_rad.to_degrees()
        ));
    }
    out.push(match of(AmbiguityKind::Congruent).next() {
        None => format!("verdict: no congruent configuration of {} or more landmarks", min_size.max(3)),
        Some(first) => format!(
            "verdict: AMBIGUOUS layout ({at_least}{congruent} congruent configurations, largest {}{} landmarks): expect `ambiguous` poses there until motion resolves them",
            at_least,
            first.size()
        ),
    });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::map_of as map;

    #[test]
    fn finds_a_repeated_triangle_and_not_a_random_one() {
        // Triangle (0,0),(1.3,0),(0.4,0.9) repeated at +5 m in x: congruent.
        let m = map(&[
            (0.0, 0.0),
            (1.3, 0.0),
            (0.4, 0.9),
            (5.0, 0.0),
            (6.3, 0.0),
            (5.4, 0.9),
            (2.7, 3.1),
        ]);
        let a = find_ambiguities(&m, 0.02, 3.0, 3);
        let c: Vec<_> = a
            .iter()
            .filter(|x| x.kind == AmbiguityKind::Congruent)
            .collect();
        assert!(!c.is_empty());
        assert_eq!(c[0].size(), 3);
        let m = map(&[
            (0.0, 0.0),
            (1.3, 0.0),
            (0.4, 0.9),
            (5.0, 0.2),
            (6.1, 0.7),
            (5.9, 2.0),
        ]);
        assert!(find_ambiguities(&m, 0.02, 3.0, 3)
            .iter()
            .all(|x| x.kind == AmbiguityKind::Mirror || x.size() < 3));
    }

    /// Reflectors in pairs 15 cm apart: every subset moved 15 cm lands on its twins, which a
    /// scan sees beside it, so the layout is no ambiguity (`lrf localize --global-only` found
    /// 100 ok poses of 100); it used to be called AMBIGUOUS with 175 congruent configurations.
    /// A triangle repeated 5 m away still is one, twins or not.
    #[test]
    fn twins_in_view_are_no_ambiguity() {
        let base = [(0.0, 0.0), (1.3, 0.2), (0.4, 0.9), (2.1, 1.7), (3.0, 0.4)];
        let twins: Vec<(f64, f64)> = base
            .iter()
            .flat_map(|&(x, y)| [(x, y), (x + 0.15, y)])
            .collect();
        // Congruent configurations moved `by` metres without turning (two parallel pairs of
        // these reflectors, which face nowhere, are also a parallelogram turned 180°).
        let congruent = |m: &Map, by: f64| {
            find_ambiguities(m, 0.03, 5.6, 3)
                .into_iter()
                .filter(|x| {
                    x.kind == AmbiguityKind::Congruent
                        && (x.transform.position().coords.norm() - by).abs() < 0.01
                        && x.transform.theta_rad.abs() < 0.01
                })
                .count()
        };
        assert_eq!(congruent(&map(&twins), 0.15), 0);
        let mut repeated = twins.clone();
        repeated.extend(base.iter().take(3).map(|&(x, y)| (x + 9.0, y)));
        assert!(congruent(&map(&repeated), 9.0) > 0);
    }
}
