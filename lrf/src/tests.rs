//! Unit tests of search and tracking on a tiny local generator (perfect
//! geometry, beams set only where reflectors are; no synth dependency).

use nalgebra::Point2;
use odocal_core::{wrap_angle, Pose2};

use crate::*;

/// A map of point landmarks (ids from 1) without facing or visibility limits.
pub(crate) fn map_of(pts: &[(f64, f64)]) -> Map {
    let landmarks = pts
        .iter()
        .enumerate()
        .map(|(k, &(x, y))| LandmarkSpec {
            id: k as u32 + 1,
            x_m: x,
            y_m: y,
            facing_rad: None,
            half_fov_rad: None,
            visibility_line: None,
        })
        .collect();
    Map::from_file(
        &MapFile {
            format: MAP_FORMAT.into(),
            reflector_width_m: 0.08,
            landmarks,
            walls: vec![],
            position_sigma_m: None,
            room_m: None,
        },
        "test",
    )
    .unwrap()
}

/// A scan from `pose`: reflector beams at every landmark in range (except
/// `skip`), plus reflector-sized spurious returns at `extra` sensor-frame points.
fn scan_of(map: &Map, pose: &Pose2, skip: &[usize], extra: &[Point2<f64>]) -> Scan {
    let cfg = SensorConfig::default();
    let n = (cfg.fov_rad / cfg.step_rad) as usize + 1;
    let a0 = -0.5 * (n - 1) as f64 * cfg.step_rad;
    let angles: Vec<f64> = (0..n).map(|k| a0 + k as f64 * cfg.step_rad).collect();
    // Every beam that misses the reflectors returns from a dark wall at the range limit, as in
    // a room: only a return from beyond a landmark shows it missed.
    let mut ranges = vec![cfg.max_range_m; n];
    let mut inten = vec![0.0; n];
    let inv = pose.inverse();
    let mut pts: Vec<Point2<f64>> = (0..map.len())
        .filter(|l| !skip.contains(l))
        .map(|l| inv.transform_point(&map.position(l)))
        .collect();
    pts.extend_from_slice(extra);
    for p in pts {
        let rho = p.coords.norm();
        let beta = p.y.atan2(p.x);
        if rho > cfg.max_range_m {
            continue;
        }
        for (k, a) in angles.iter().enumerate() {
            if wrap_angle(a - beta).abs() * rho <= 0.04 {
                ranges[k] = rho;
                inten[k] = 1.0;
            }
        }
    }
    Scan {
        id: 0,
        t_s: None,
        angles_rad: angles,
        ranges_m: ranges,
        intensities: inten,
        reversed: false,
    }
}

const PTS: [(f64, f64); 8] = [
    (0.0, 0.0),
    (3.1, 0.4),
    (1.2, 2.7),
    (4.0, 3.3),
    (-1.5, 2.2),
    (2.2, -1.9),
    (5.3, 0.9),
    (-0.7, -2.4),
];

#[test]
fn global_finds_the_pose_despite_a_miss_and_a_spurious_return() {
    let loc = Localizer::new(map_of(&PTS), LocalizerConfig::default());
    let truth = Pose2::new(1.4, 0.6, 0.7);
    let scan = scan_of(&loc.map, &truth, &[3], &[Point2::new(1.0, -1.7)]);
    let dets = loc.detections(&scan);
    assert!(dets.len() >= 6, "{}", dets.len());
    let g = loc.global(&scan, &dets);
    assert_eq!(g.status, Status::Ok, "{g:?}");
    let b = g.best().unwrap();
    assert!(
        (b.pose.position() - truth.position()).norm() < 0.01,
        "{:?}",
        b.pose
    );
    assert!(wrap_angle(b.pose.theta_rad - truth.theta_rad).abs() < 0.003);
    assert_eq!(
        b.matches.len(),
        dets.len() - 1,
        "all but the spurious return"
    );
    assert!((b.helmert_scale - 1.0).abs() < 0.005);
    // The landmark skipped at index 3 is in view: negative evidence counts it.
    assert_eq!(b.n_missing, 1);
    // Brute force finds the same pose.
    let bf = loc.global_brute_force(&scan, &dets);
    assert!((bf.best().unwrap().pose.position() - b.pose.position()).norm() < 1e-9);
}

#[test]
fn source_search_works_only_without_spurious_returns() {
    let loc = Localizer::new(map_of(&PTS), LocalizerConfig::default());
    let truth = Pose2::new(1.4, 0.6, 0.7);
    let clean = scan_of(&loc.map, &truth, &[], &[]);
    let h = loc.source_search(&loc.detections(&clean));
    assert_eq!(h.len(), 1);
    assert!((h[0].pose.position() - truth.position()).norm() < 0.01);
    let dirty = scan_of(&loc.map, &truth, &[], &[Point2::new(1.0, -1.7)]);
    assert!(loc.source_search(&loc.detections(&dirty)).is_empty());
}

#[test]
fn symmetric_square_is_ambiguous_never_confidently_wrong() {
    // A square of 4 landmarks: 4 rotations fit equally well.
    let loc = Localizer::new(
        map_of(&[(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]),
        LocalizerConfig::default(),
    );
    let truth = Pose2::new(1.0, 0.7, 0.3);
    let scan = scan_of(&loc.map, &truth, &[], &[]);
    let g = loc.global(&scan, &loc.detections(&scan));
    assert_eq!(g.status, Status::Ambiguous);
    assert_eq!(g.hypotheses.len(), 4);
    assert!(g
        .hypotheses
        .iter()
        .any(|h| (h.pose.position() - truth.position()).norm() < 0.01));
}

#[test]
fn too_few_detections_is_lost() {
    let loc = Localizer::new(map_of(&PTS), LocalizerConfig::default());
    let scan = scan_of(
        &loc.map,
        &Pose2::new(1.4, 0.6, 0.7),
        &[0, 1, 2, 3, 4, 5],
        &[],
    );
    assert_eq!(
        loc.global(&scan, &loc.detections(&scan)).status,
        Status::Lost
    );
}

#[test]
fn tracker_follows_motion() {
    let loc = Localizer::new(map_of(&PTS), LocalizerConfig::default());
    let mut tr = ScanTracker::new(&loc);
    for k in 0..20 {
        let t = k as f64 * 0.1;
        let truth = Pose2::new(1.0 + 0.05 * k as f64, 0.5, 0.2 + 0.02 * k as f64);
        let r = tr.process(&scan_of(&loc.map, &truth, &[k % 8], &[]), t);
        assert_eq!(r.status, Status::Ok, "scan {k}: {r:?}");
        assert_eq!(r.mode, if k == 0 { "global" } else { "track" });
        assert!((r.pose.unwrap().position() - truth.position()).norm() < 0.01);
    }
}

#[test]
fn history_resolves_a_symmetric_start() {
    // A square (4-fold ambiguous) and one landmark that only comes into view
    // as the sensor drives towards it.
    let loc = Localizer::new(
        map_of(&[(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0), (-0.5, -5.0)]),
        LocalizerConfig::default(),
    );
    let mut tr = ScanTracker::new(&loc);
    let mut statuses = Vec::new();
    for k in 0..40 {
        let truth = Pose2::new(-1.5, 1.0 - 0.04 * k as f64, 0.0);
        let r = tr.process(&scan_of(&loc.map, &truth, &[], &[]), k as f64 * 0.1);
        if r.status == Status::Ok {
            let p = r.pose.unwrap();
            assert!(
                (p.position() - truth.position()).norm() < 0.03,
                "scan {k}: confident wrong {p:?}"
            );
        }
        statuses.push(r.status);
    }
    assert_eq!(statuses[0], Status::Ambiguous);
    assert_eq!(*statuses.last().unwrap(), Status::Ok, "{statuses:?}");
}

/// [`PTS`] in a room whose walls are all within the scanner's range.
fn walled_map() -> Map {
    let (x0, y0, x1, y1) = (-3.0, -4.0, 7.0, 5.0);
    let mut file = MapFile {
        format: MAP_FORMAT.into(),
        reflector_width_m: 0.08,
        landmarks: Vec::new(),
        walls: vec![
            [x0, y0, x1, y0],
            [x1, y0, x1, y1],
            [x1, y1, x0, y1],
            [x0, y1, x0, y0],
        ],
        position_sigma_m: None,
        room_m: None,
    };
    file.landmarks = map_of(&PTS)
        .landmarks
        .iter()
        .map(|l| LandmarkSpec {
            id: l.id,
            x_m: l.position.x,
            y_m: l.position.y,
            facing_rad: None,
            half_fov_rad: None,
            visibility_line: None,
        })
        .collect();
    Map::from_file(&file, "walled").unwrap()
}

/// Beams with no return in front of mapped walls (a dark or glass wall, dropouts; written 0 or,
/// as ROS drivers do, infinite) are no evidence against a pose: the reflectors alone fix it.
/// A return beyond a wall still is.
#[test]
fn beams_without_a_return_are_not_free_space() {
    let loc = Localizer::new(walled_map(), LocalizerConfig::default());
    let truth = Pose2::new(1.4, 0.6, 0.7);
    // Only the reflectors return; every other beam, all of them aimed at a wall within
    // range, has none.
    let mut zero = scan_of(&loc.map, &truth, &[], &[]);
    for (r, i) in zero.ranges_m.iter_mut().zip(&zero.intensities) {
        if *i == 0.0 {
            *r = 0.0;
        }
    }
    let mut inf = zero.clone();
    for r in inf.ranges_m.iter_mut().filter(|r| **r == 0.0) {
        *r = f64::INFINITY;
    }
    for scan in [&zero, &inf] {
        assert_eq!(loc.free_space_violations(scan, &truth), 0);
        let g = loc.global(scan, &loc.detections(scan));
        assert_eq!(g.status, Status::Ok, "{g:?}");
        let b = g.best().unwrap();
        assert!((b.pose.position() - truth.position()).norm() < 0.01);
    }
    // Returns from 20 m, through the walls: every checked beam contradicts the map.
    let mut through = zero.clone();
    for r in through.ranges_m.iter_mut().filter(|r| **r == 0.0) {
        *r = 20.0;
    }
    let checked = zero.ranges_m.len().div_ceil(8);
    assert!(
        loc.free_space_violations(&through, &truth) > checked / 2,
        "{} of {checked}",
        loc.free_space_violations(&through, &truth)
    );
}
