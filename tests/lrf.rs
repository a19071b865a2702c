//! Laser positioning: acceptance on seeded synthetic scans (library level)
//! and the `odocal synth lrf` / `odocal lrf` commands end to end.

use std::path::Path;
use std::process::Command;

use nalgebra::Matrix2;
use odocal_lrf::{
    check_beam_step, evaluate, EstimatedPose, Evaluation, LaserTruth, Localizer, LocalizerConfig,
    Map, Scan, ScanTracker, Status, TruthPose,
};
use odocal_synth::lrf_sim::{simulate, LrfSim, LrfSimConfig};

fn scans_of(sim: &LrfSim) -> Vec<Scan> {
    sim.scans
        .iter()
        .map(|s| Scan {
            id: s.id,
            t_s: Some(s.t_s),
            angles_rad: s.angles_rad.clone(),
            ranges_m: s.ranges_m.clone(),
            intensities: s.intensities.clone(),
            reversed: false,
        })
        .collect()
}

fn truth_of(sim: &LrfSim) -> LaserTruth {
    LaserTruth::new(
        sim.scans
            .iter()
            .map(|s| TruthPose {
                t_s: s.t_s,
                pose: s.truth,
                n_detected: Some(s.n_detected),
            })
            .collect(),
    )
    .expect("the simulator's scans are in time order")
}

/// The tracker's poses of a scan sequence.
fn track(loc: &Localizer, scans: &[Scan]) -> Vec<EstimatedPose> {
    let mut tracker = ScanTracker::new(loc);
    scans
        .iter()
        .map(|s| {
            let r = tracker.process(s, s.t_s.unwrap_or(0.0));
            EstimatedPose {
                t_s: r.t_s,
                status: r.status,
                pose: r.pose,
                n_landmarks: r.n_landmarks,
                cov: r.pose_cov,
            }
        })
        .collect()
}

/// Global (no prior) and tracking evaluations of one simulated sequence.
fn run(cfg: &LrfSimConfig) -> (LrfSim, Localizer, Evaluation, Evaluation) {
    let sim = simulate(cfg);
    let map = Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
    let loc = Localizer::new(map, LocalizerConfig::default());
    let scans = scans_of(&sim);
    let truth = truth_of(&sim);
    let global: Vec<_> = scans
        .iter()
        .map(|s| {
            let d = loc.detections(s);
            let g = loc.global(s, &d);
            let b = g.best();
            EstimatedPose {
                t_s: s.t_s.unwrap_or(0.0),
                status: g.status,
                pose: b.map(|h| h.pose),
                n_landmarks: b.map_or(0, |h| h.matches.len()),
                cov: b.and_then(|h| h.cov),
            }
        })
        .collect();
    let tracked = track(&loc, &scans);
    let eg = evaluate(&global, &truth);
    let et = evaluate(&tracked, &truth);
    (sim, loc, eg, et)
}

fn report(name: &str, e: &Evaluation) {
    println!(
        "{name}: {} scans, ok {}, ambiguous {}, lost {}; position RMS {:.2} mm, heading RMS {:.3} deg over {} scans; correct {}/{} ({:.2} %); confident wrong {}",
        e.n_scans,
        e.n_ok,
        e.n_ambiguous,
        e.n_lost,
        e.position_rms_m * 1e3,
        e.heading_rms_rad.to_degrees(),
        e.n_accuracy,
        e.n_correct_eligible,
        e.n_eligible,
        100.0 * e.n_correct_eligible as f64 / e.n_eligible as f64,
        e.n_wrong_ok
    );
}

#[test]
fn acceptance_30_landmarks_10_by_8_room() {
    for seed in [1, 2] {
        let cfg = LrfSimConfig {
            seed,
            ..LrfSimConfig::default()
        };
        assert_eq!(
            (
                cfg.n_landmarks,
                cfg.room_w_m,
                cfg.room_h_m,
                cfg.sigma_range_m,
                cfg.p_missed,
                cfg.spurious_ratio
            ),
            (30, 10.0, 8.0, 0.01, 0.1, 0.2)
        );
        let (sim, _, g, t) = run(&cfg);
        let (det, spur, missed) = sim.summary();
        println!(
            "seed {seed}: {det:.2} detected and {spur:.2} spurious per scan, missed {:.1} %",
            missed * 100.0
        );
        // The simulator delivers the conditions of the acceptance test.
        assert!(
            (0.15..0.25).contains(&(spur / det)),
            "spurious ratio {}",
            spur / det
        );
        assert!((0.07..0.13).contains(&missed), "missed {missed}");
        report(&format!("seed {seed} global"), &g);
        report(&format!("seed {seed} tracking"), &t);
        for e in [&g, &t] {
            assert!(
                e.n_eligible >= 250,
                "too few scans with >= 3 landmarks: {}",
                e.n_eligible
            );
            assert!(e.n_accuracy >= 250);
            assert!(
                e.position_rms_m <= 0.010,
                "position RMS {} m",
                e.position_rms_m
            );
            assert!(
                e.heading_rms_rad <= 0.3f64.to_radians(),
                "heading RMS {} rad",
                e.heading_rms_rad
            );
            assert!(
                e.n_correct_eligible as f64 >= 0.99 * e.n_eligible as f64,
                "correct on {}/{}",
                e.n_correct_eligible,
                e.n_eligible
            );
            assert_eq!(e.n_wrong_ok, 0, "confident wrong poses");
        }
    }
}

/// The covariance of every detection's strip centre, as the pose fit and its Cramér–Rao bound
/// use it, against the simulator's errors: each detection matched to its landmark with the
/// true pose, its squared error in units of its covariance (chi-square with 2 degrees of
/// freedom if the covariance is right) averages 2. The covariance known before association
/// (`Detection::cov`, the gates' bound) is not this: radially too small, across too large.
#[test]
fn detection_covariances_match_the_simulated_errors() {
    for (n, seed) in [(30, 1), (200, 2)] {
        let sim = simulate(&LrfSimConfig::scaled(n, seed));
        let map = Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
        let loc = Localizer::new(map, LocalizerConfig::default());
        let (mut sum, mut n_det, mut n_far) = (0.0, 0usize, 0usize);
        for (scan, s) in scans_of(&sim).iter().zip(&sim.scans) {
            let iso = s.truth.isometry();
            let to_sensor = nalgebra::Rotation2::new(-s.truth.theta_rad);
            for d in loc.detections(scan) {
                let Some((l, _)) = loc.map.nearest_within(&(iso * d.point), 0.05, |_| true) else {
                    continue; // a spurious glint
                };
                let lm = &loc.map.landmarks[l];
                let normal = lm.facing.map(|f| to_sensor * f);
                let (centre, cov) = d.strip_centre(
                    normal,
                    lm.half_fov_rad,
                    loc.map.reflector_width_m,
                    &loc.cfg.sensor,
                );
                let e = centre - iso.inverse() * lm.position;
                let w: Matrix2<f64> = cov.try_inverse().expect("covariance is invertible");
                let nees = e.dot(&(w * e));
                // Beyond 20 (chance 5e-5) the detection is a glint beside a landmark, taken
                // for it here.
                if nees > 20.0 {
                    n_far += 1;
                } else {
                    sum += nees;
                    n_det += 1;
                }
            }
        }
        let mean = sum / n_det as f64;
        println!(
            "N = {n}, seed {seed}: {n_det} detections, mean squared error in units of the covariance {mean:.3} (2 if right), {n_far} beyond 20"
        );
        assert!(n_det >= 1500, "{n_det} detections");
        assert!((1.85..2.15).contains(&mean), "mean {mean}, should be 2");
        assert!(n_far * 100 <= n_det, "{n_far} far errors of {n_det}");
    }
}

/// The pose of a scan is at its noise floor: for N = 30, 100 and 200 landmarks (three seeds of
/// 300 scans each, tracked as `odocal lrf localize` does) the position RMS is at most 1.1 times
/// its Cramér–Rao bound, from the matched detections' covariances (checked against the
/// simulator above) and the landmark geometry, and so is the heading's. Fitting every detection
/// alike, as before the weighted fit, the position was 1.4–1.6 times the bound.
#[test]
fn poses_reach_the_cramer_rao_bound() {
    for n in [30, 100, 200] {
        let (mut sp, mut sh, mut bp, mut bh, mut k) = (0.0, 0.0, 0.0, 0.0, 0usize);
        for seed in 1..=3 {
            let sim = simulate(&LrfSimConfig::scaled(n, seed));
            let map = Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
            let loc = Localizer::new(map, LocalizerConfig::default());
            let e = evaluate(&track(&loc, &scans_of(&sim)), &truth_of(&sim));
            assert_eq!(e.n_bound, e.n_accuracy, "every ok pose has its bound");
            assert!(e.n_accuracy >= 250, "{} ok scans", e.n_accuracy);
            let w = e.n_accuracy as f64;
            sp += w * e.position_rms_m.powi(2);
            sh += w * e.heading_rms_rad.powi(2);
            bp += w * e.position_crb_m.powi(2);
            bh += w * e.heading_crb_rad.powi(2);
            k += e.n_accuracy;
        }
        let (pos, pos_crb) = ((sp / k as f64).sqrt(), (bp / k as f64).sqrt());
        let (head, head_crb) = ((sh / k as f64).sqrt(), (bh / k as f64).sqrt());
        println!(
            "N = {n}: {k} scans; position RMS {:.2} mm (Cramér–Rao bound {:.2} mm, ratio {:.3}), heading RMS {:.4} deg (bound {:.4} deg, ratio {:.3})",
            pos * 1e3,
            pos_crb * 1e3,
            pos / pos_crb,
            head.to_degrees(),
            head_crb.to_degrees(),
            head / head_crb
        );
        assert!(
            pos <= 1.1 * pos_crb,
            "N = {n}: position {pos} m, bound {pos_crb} m"
        );
        assert!(
            head <= 1.1 * head_crb,
            "N = {n}: heading {head} rad, bound {head_crb} rad"
        );
    }
}

/// A scanner logged at every 4th beam (1.4°; seed 3, the user's case) or every 3rd (1.05°;
/// seed 4) hits most reflectors with one beam, which places a detection along its strip only
/// within a beam spacing (7 cm at 3 m). A glint beside a landmark then fitted the rigid fit's
/// loose gates: seed 3's scan 190 was `ok` with 5 landmarks, 140 mm off with a σ of 9 mm
/// (error/σ 15.7), and seed 4's scan 287 was 97 mm off (14.6). Now every `ok` pose is right or
/// its σ covers the error, and the step is called too coarse; at the full step it is not.
#[test]
fn coarse_beam_steps_give_no_confident_wrong_pose() {
    for (seed, every) in [(3, 4), (4, 3)] {
        let sim = simulate(&LrfSimConfig {
            seed,
            ..LrfSimConfig::default()
        });
        let map = Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
        let full = scans_of(&sim);
        let coarse: Vec<Scan> = full
            .iter()
            .map(|s| {
                let keep = |v: &[f64]| v.iter().step_by(every).copied().collect::<Vec<f64>>();
                Scan {
                    angles_rad: keep(&s.angles_rad),
                    ranges_m: keep(&s.ranges_m),
                    intensities: keep(&s.intensities),
                    ..s.clone()
                }
            })
            .collect();
        let mut cfg = LocalizerConfig::default();
        let fine = Localizer::new(map.clone(), cfg);
        assert_eq!(check_beam_step(&fine, &full), None);
        cfg.sensor.step_rad = coarse[0].step_rad();
        let loc = Localizer::new(map, cfg);
        let warning = check_beam_step(&loc, &coarse).expect("the step is called too coarse");
        assert!(warning.contains("record every beam"), "{warning}");
        let poses = track(&loc, &coarse);
        let truth = truth_of(&sim);
        let e = evaluate(&poses, &truth);
        let (mut z2, mut z_max, mut n) = (0.0, 0.0f64, 0usize);
        for p in poses.iter().filter(|p| p.status == Status::Ok) {
            let (Some(pose), Some(cov), Some(t)) = (p.pose, p.cov, truth.at(p.t_s)) else {
                panic!("an ok pose at {} s without its σ or truth", p.t_s);
            };
            for (err, var) in [
                (pose.x_m - t.pose.x_m, cov[(0, 0)]),
                (pose.y_m - t.pose.y_m, cov[(1, 1)]),
            ] {
                let z = err / var.sqrt();
                z2 += z * z;
                z_max = z_max.max(z.abs());
                n += 1;
            }
        }
        let z_rms = (z2 / n as f64).sqrt();
        println!(
            "seed {seed}, 1 beam in {every}: {} ok, position RMS {:.1} mm, max {:.1} mm; error/σ RMS {z_rms:.2}, max {z_max:.1}; confident wrong {}",
            e.n_ok,
            e.position_rms_m * 1e3,
            e.position_max_m * 1e3,
            e.n_wrong_ok
        );
        assert!(e.n_ok >= 240, "{} ok", e.n_ok);
        assert_eq!(e.n_wrong_ok, 0, "confident wrong poses");
        assert!(z_max <= 5.0, "error/σ up to {z_max}");
        assert!((0.8..=1.2).contains(&z_rms), "error/σ RMS {z_rms}");
    }
}

/// `scan` (beams at `a0 + i·step`) as a full turn of its step whose array starts at the beam
/// nearest `start_rad` (on the scanner's own beam grid), its angles running on from there
/// (up to 5π/2 from π/2), the directions it did not scan filled with `rear` (range, intensity).
fn as_turn_from(scan: &Scan, start_rad: f64, rear: (f64, f64)) -> Scan {
    let (a0, step) = (scan.angles_rad[0], scan.step_rad());
    let n = (std::f64::consts::TAU / step).round() as i64;
    let k0 = ((start_rad - a0) / step).round() as i64;
    let mut turn = Scan {
        angles_rad: Vec::new(),
        ranges_m: Vec::new(),
        intensities: Vec::new(),
        ..scan.clone()
    };
    for k in k0..k0 + n {
        let i = k.rem_euclid(n) as usize;
        let (r, v) = match (scan.ranges_m.get(i), scan.intensities.get(i)) {
            (Some(&r), Some(&v)) => (r, v),
            _ => rear,
        };
        turn.angles_rad.push(a0 + k as f64 * step);
        turn.ranges_m.push(r);
        turn.intensities.push(v);
    }
    turn
}

/// A 360° scan gives the same poses, σ and statuses wherever its array starts. Written from 0
/// to 2π (or from −π/2), its first and last beams used to be taken for the edges of the view
/// and a reflector across them cut in two: `synth lrf --scans 100` as a full turn from 0 gave
/// 3.6 mm RMS at 1.30 times the Cramér–Rao bound against 3.0 mm and 1.06 from −π, and one
/// scan ok 18.5 mm (9σ) off. Three scanners: a 240° one whose rear is masked (no return), a
/// 360° one (reflectors all round; walls beyond its range return nothing), and the same with
/// a return in every direction (no sector to put the seam in).
#[test]
fn a_full_turn_gives_the_same_poses_wherever_its_array_starts() {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let masked = simulate(&LrfSimConfig {
        n_scans: 40,
        seed: 5,
        ..LrfSimConfig::default()
    });
    let step = LrfSimConfig::default().step_rad;
    let all_round = simulate(&LrfSimConfig {
        n_scans: 40,
        seed: 5,
        fov_rad: TAU - 0.5 * step,
        ..LrfSimConfig::default()
    });
    let map = |sim: &LrfSim| Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
    let mut closed = scans_of(&all_round);
    for s in &mut closed {
        for r in s
            .ranges_m
            .iter_mut()
            .filter(|r| **r < 0.02 || r.is_infinite())
        {
            *r = 5.6;
        }
    }
    let cases = [
        ("masked rear", map(&masked), scans_of(&masked)),
        ("360°", map(&all_round), scans_of(&all_round)),
        ("360°, a return all round", map(&all_round), closed),
    ];
    for (name, map, scans) in cases {
        let loc = Localizer::new(map, LocalizerConfig::default());
        let turn = |start_rad: f64| -> Vec<EstimatedPose> {
            let turned: Vec<Scan> = scans
                .iter()
                .map(|s| as_turn_from(s, start_rad, (f64::INFINITY, 0.0)))
                .collect();
            track(&loc, &turned)
        };
        let reference = turn(-PI);
        let ok = reference.iter().filter(|p| p.status == Status::Ok).count();
        println!("{name}: {ok} ok of 40 from −π");
        assert!(ok >= 36, "{name}: {ok} ok of 40 from −π");
        for start_rad in [0.0, -FRAC_PI_2, FRAC_PI_2, -2.5, 1.0] {
            for (a, b) in turn(start_rad).iter().zip(&reference) {
                let same = match (a.pose, b.pose, a.cov, b.cov) {
                    (Some(p), Some(q), Some(c), Some(d)) => {
                        (p.position() - q.position()).norm() < 1e-9
                            && (p.theta_rad - q.theta_rad).abs() < 1e-9
                            && (c - d).norm() <= 1e-9 * d.norm()
                    }
                    (p, q, _, _) => p.is_none() && q.is_none(),
                };
                assert!(
                    same && a.status == b.status && a.n_landmarks == b.n_landmarks,
                    "{name}, start {start_rad} rad, t {} s: {:?} {:?} ({} landmarks) against {:?} {:?} ({}) from −π",
                    a.t_s,
                    a.status,
                    a.pose,
                    a.n_landmarks,
                    b.status,
                    b.pose,
                    b.n_landmarks
                );
            }
        }
    }
}

#[test]
fn symmetric_layout_never_gives_a_confident_wrong_pose() {
    let cfg = LrfSimConfig {
        symmetric: true,
        seed: 3,
        ..LrfSimConfig::default()
    };
    let (sim, loc, g, t) = run(&cfg);
    report("symmetric global", &g);
    report("symmetric tracking", &t);
    assert_eq!(g.n_wrong_ok, 0);
    assert_eq!(t.n_wrong_ok, 0);
    // Not by giving up: most scans with >= 3 landmarks are reported ambiguous
    // with the true pose among the hypotheses (and its 180° twin).
    let mut with_truth = 0;
    let mut eligible = 0;
    for (s, scan) in sim.scans.iter().zip(scans_of(&sim)) {
        if s.n_detected < 3 {
            continue;
        }
        eligible += 1;
        let l = loc.global(&scan, &loc.detections(&scan));
        let has_truth = l
            .hypotheses
            .iter()
            .any(|h| (h.pose.position() - s.truth.position()).norm() < 0.05);
        if l.status == Status::Ambiguous && has_truth && l.hypotheses.len() >= 2 {
            with_truth += 1;
        }
    }
    println!("symmetric: {with_truth}/{eligible} eligible scans ambiguous with the truth among the hypotheses");
    assert!(eligible >= 100);
    assert!(
        with_truth as f64 >= 0.9 * eligible as f64,
        "{with_truth}/{eligible}"
    );
}

fn odocal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(args)
        .output()
        .expect("run odocal")
}

/// The header and the rows (their fields) of `synth lrf`'s scans.csv in `dir`.
fn scan_rows(dir: &Path) -> (String, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("scans.csv")).expect("scans");
    let mut lines = text.lines();
    let header = lines.next().expect("header").to_string();
    assert_eq!(header, "scan,t,angle,range,intensity");
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

/// Writes `path` with `header` and, for each scan of `rows` (consecutive rows of one scan
/// number), the lines `per_scan` makes of it.
fn rewrite_scans(
    path: &Path,
    header: &str,
    rows: &[Vec<String>],
    per_scan: &dyn Fn(&[Vec<String>]) -> Vec<String>,
) -> std::path::PathBuf {
    let mut out = vec![header.to_string()];
    for scan in rows.chunk_by(|a, b| a[0] == b[0]) {
        out.extend(per_scan(scan));
    }
    std::fs::write(path, out.join("\n") + "\n").expect("write");
    path.to_path_buf()
}

/// `odocal synth lrf` into `dir` with `seed` and `scans` scans.
fn synth_lrf(dir: &Path, seed: u64, scans: usize) {
    synth_lrf_with(dir, seed, scans, &[]);
}

/// [`synth_lrf`] with `extra` options.
fn synth_lrf_with(dir: &Path, seed: u64, scans: usize, extra: &[&str]) {
    let (seed, scans) = (seed.to_string(), scans.to_string());
    let mut args = vec![
        "synth",
        "lrf",
        "--out",
        s(dir),
        "--seed",
        &seed,
        "--scans",
        &scans,
    ];
    args.extend_from_slice(extra);
    let out = odocal(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `odocal lrf localize` of `synth lrf`'s scans in `d` with its map, into `d/poses.csv`, with
/// `extra` options.
fn localize(d: &Path, extra: &[&str]) -> std::process::Output {
    localize_into(d, &d.join("poses.csv"), extra)
}

/// [`localize`] into `out`.
fn localize_into(d: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let (map, scans) = (d.join("map.json"), d.join("scans.csv"));
    let mut args = vec![
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&scans),
        "--out",
        s(out),
    ];
    args.extend(extra);
    odocal(&args)
}

/// `lrf localize` of `scans` with `map` into `poses` and the trajectory `traj`, judged
/// against `truth`: the run, which must succeed.
fn localize_judged(
    map: &Path,
    scans: &Path,
    poses: &Path,
    traj: &Path,
    truth: &Path,
) -> std::process::Output {
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(map),
        s(scans),
        "--out",
        s(poses),
        "--trajectory",
        s(traj),
        "--truth",
        s(truth),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn cli_synth_then_localize_with_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 4, 120);
    let first = std::fs::read(d.join("scans.csv")).expect("scans");
    // Same seed, same bytes.
    let d2 = d.join("again");
    let out = odocal(&[
        "synth",
        "lrf",
        "--out",
        s(&d2),
        "--seed",
        "4",
        "--scans",
        "120",
    ]);
    assert!(out.status.success());
    assert_eq!(first, std::fs::read(d2.join("scans.csv")).expect("scans"));
    assert_eq!(
        std::fs::read(d.join("map.json")).expect("map"),
        std::fs::read(d2.join("map.json")).expect("map")
    );

    let localize = |out: &Path, truth: &Path| localize_into(d, out, &["--truth", s(truth)]);
    let poses = d.join("poses.csv");
    let out = localize(&poses, &d.join("truth.csv"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("120 scans"), "{stdout}");
    assert!(
        stdout.contains("position RMS")
            && stdout.contains(" mm")
            && stdout.contains("confident wrong poses: 0")
    );
    let text = std::fs::read_to_string(&poses).expect("poses");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t,x,y,theta,status,n_landmarks,n_detections,n_hypotheses,score,mode,scan")
    );
    let truth = std::fs::read_to_string(d.join("truth.csv")).expect("truth");
    let mut n_ok = 0;
    for (row, tr) in lines.zip(truth.lines().skip(1)) {
        let f: Vec<&str> = row.split(',').collect();
        let t: Vec<f64> = tr
            .split(',')
            .take(4)
            .map(|v| v.parse().expect("number"))
            .collect();
        assert!(["ok", "ambiguous", "lost"].contains(&f[4]), "{row}");
        if f[4] == "ok" {
            n_ok += 1;
            let (x, y): (f64, f64) = (f[1].parse().expect("x"), f[2].parse().expect("y"));
            assert!((x - t[1]).hypot(y - t[2]) < 0.05, "{row} vs {tr}");
            assert!(f[5].parse::<usize>().expect("n_landmarks") >= 3);
        }
    }
    assert!(n_ok >= 100, "{n_ok} ok scans of 120");

    // The truth of other scans (every pose shifted 3 m): the poses it contradicts are refused.
    let shifted: String = truth
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
            if i > 0 {
                f[1] = (f[1].parse::<f64>().expect("x") + 3.0).to_string();
            }
            f.join(",") + "\n"
        })
        .collect();
    let other = d.join("other_truth.csv");
    std::fs::write(&other, shifted).expect("write");
    let poses2 = d.join("poses2.csv");
    let out = localize(&poses2, &other);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("confident poses are wrong against") && err.contains("other_truth.csv"),
        "{err}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("nothing written"));
    assert!(!poses2.exists());

    // One scan per file (no scan/t columns) works too, in global-only mode.
    let one = d.join("one.csv");
    let mut single = String::from("angle,range,intensity\n");
    for l in first.split(|&b| b == b'\n').skip(1).take(683) {
        let l = String::from_utf8_lossy(l);
        let f: Vec<&str> = l.split(',').collect();
        single.push_str(&format!("{},{},{}\n", f[2], f[3], f[4]));
    }
    std::fs::write(&one, single).expect("write");
    let out = odocal(&[
        "lrf",
        "localize",
        "--global-only",
        "--map",
        s(&d.join("map.json")),
        s(&one),
        "--out",
        s(&d.join("one_poses.csv")),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 scans"));
}

/// `lrf localize --truth` prints each RMS with its Cramér–Rao bound and their ratio; the
/// position and heading of 300 scans among 100 landmarks are within 1.1 times theirs.
#[test]
fn cli_prints_the_cramer_rao_bound_beside_the_rms() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let out = odocal(&["synth", "lrf", "--out", s(d), "--landmarks", "100"]);
    assert!(out.status.success());
    let out = localize(d, &["--truth", s(&d.join("truth.csv"))]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    assert!(out.status.success());
    // "position RMS 2.3 mm (Cramér–Rao bound 2.4 mm, ratio 0.96)", and so for the heading.
    let figures = |what: &str, unit: &str| -> (f64, f64, f64) {
        let start = stdout.find(what).expect("the RMS is printed") + what.len();
        let rest = &stdout[start..];
        let num = |s: &str| s.trim().parse::<f64>().expect("a number");
        let rms = num(&rest[..rest.find(unit).expect("unit")]);
        let tag = "(Cramér–Rao bound ";
        let rest = &rest[rest.find(tag).expect("bound") + tag.len()..];
        let bound = num(&rest[..rest.find(unit).expect("unit")]);
        let rest = &rest[rest.find("ratio ").expect("ratio") + "ratio ".len()..];
        let ratio = num(&rest[..rest.find(')').expect(")")]);
        (rms, bound, ratio)
    };
    for (what, unit) in [("position RMS ", " mm"), ("heading RMS ", " deg")] {
        let (rms, bound, ratio) = figures(what, unit);
        assert!(
            (rms / bound - ratio).abs() < 0.02,
            "{what}{rms} / {bound} is not {ratio}"
        );
        assert!(ratio <= 1.1, "{what}{rms}{unit}, bound {bound}{unit}");
    }
}

#[test]
fn cli_check_map_flags_the_symmetric_layout() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let sym = d.join("sym");
    assert!(odocal(&[
        "synth",
        "lrf",
        "--out",
        s(&sym),
        "--symmetric",
        "--scans",
        "1"
    ])
    .status
    .success());
    let out = odocal(&["lrf", "check-map", s(&sym.join("map.json"))]);
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}");
    assert!(out.status.success());
    assert!(text.contains("verdict: AMBIGUOUS"), "{text}");
    // Said on stderr as a warning too (it was only a stdout line, exit 0).
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning: ") && err.contains("map.json: AMBIGUOUS layout ("),
        "{err}"
    );
    let rnd = d.join("rnd");
    assert!(odocal(&["synth", "lrf", "--out", s(&rnd), "--scans", "1"])
        .status
        .success());
    let out = odocal(&["lrf", "check-map", s(&rnd.join("map.json"))]);
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}");
    assert!(out.status.success());
    assert!(
        text.contains("verdict: no congruent configuration"),
        "{text}"
    );
    assert!(!String::from_utf8_lossy(&out.stderr).contains("AMBIGUOUS"));
}

/// Runs odocal expecting exit code 2 and a one-line error containing `want`.
fn expect_error(args: &[&str], want: &str) -> String {
    let out = odocal(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.starts_with("odocal: error: "), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.contains(want), "{args:?}: expected {want:?} in {err}");
    err
}

/// Keys of a landmark map that odocal does not read were passed over, and the defaults took
/// their place: landmarks facing `facing_deg` were read as visible from everywhere, and the
/// poses' heading RMS was 2.48 times its bound with no word. Each is refused, naming the key,
/// its line and column and the keys known there; a value of the wrong type names its key.
#[test]
fn cli_unknown_map_keys_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 3);
    let map = std::fs::read_to_string(d.join("map.json")).expect("map");
    for (from, to, known) in [
        (
            "\"facing_rad\"",
            "facing_deg",
            "`id`, `x_m`, `y_m`, `facing_rad`, `half_fov_rad`, `visibility_line`",
        ),
        (
            "\"position_sigma_m\"",
            "position_sigma_mm",
            "`format`, `reflector_width_m`, `landmarks`, `walls`, `position_sigma_m`, `room_m`",
        ),
        (
            "\"reflector_width_m\"",
            "reflector_width",
            "`format`, `reflector_width_m`, `landmarks`, `walls`, `position_sigma_m`, `room_m`",
        ),
        ("\"visible\"", "side", "`a`, `b`, `x_m`, `visible`"),
    ] {
        let edited = map.replacen(from, &format!("\"{to}\""), 1);
        let line = edited
            .lines()
            .position(|l| l.contains(&format!("\"{to}\"")))
            .expect("the key")
            + 1;
        let bad = d.join(format!("{to}.json"));
        std::fs::write(&bad, edited).expect("write");
        for cmd in [
            vec!["lrf", "check-map", s(&bad)],
            vec![
                "lrf",
                "localize",
                "--map",
                s(&bad),
                s(&d.join("scans.csv")),
                "--out",
                s(&d.join("poses.csv")),
            ],
        ] {
            let e = expect_error(&cmd, &format!("{}:{line}:", s(&bad)));
            assert!(
                e.contains(&format!("unknown field `{to}`, expected one of {known}")),
                "{e}"
            );
            assert!(e.contains("or remove it"), "{e}");
        }
    }
    assert!(!d.join("poses.csv").exists());
    // A string where a number belongs was named by its type alone ("invalid type: string
    // \"3\", expected u32"): its key is named too.
    let edited = map.replacen("\"id\": 3,", "\"id\": \"3\",", 1);
    assert_ne!(edited, map);
    let bad = d.join("string_id.json");
    std::fs::write(&bad, edited).expect("write");
    let e = expect_error(
        &["lrf", "check-map", s(&bad)],
        "invalid type: string \"3\", expected u32",
    );
    assert!(
        e.contains(": the value of `id`; give it as the type expected (a number without quotes)"),
        "{e}"
    );
}

/// The pose log's `score` column had no meaning or unit said anywhere.
#[test]
fn cli_localize_help_says_what_the_score_is() {
    let out = odocal(&["lrf", "localize", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.contains("score: landmarks matched minus landmarks in view from the pose that were not detected (a count, no unit; 0 when lost"),
        "{help}"
    );
}

#[test]
fn cli_bad_input_exits_with_code_2() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let w = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).expect("write");
        p
    };
    let lm = |id: u32, x: f64, y: f64| format!(r#"{{"id": {id}, "x_m": {x}, "y_m": {y}}}"#);
    let good = w(
        "good.json",
        &format!(
            r#"{{"format": "odocal.lrf-map/1", "landmarks": [{}, {}, {}]}}"#,
            lm(1, 0.0, 0.0),
            lm(2, 2.0, 0.0),
            lm(3, 0.0, 2.0)
        ),
    );
    let dup = w(
        "dup.json",
        &format!(
            r#"{{"format": "odocal.lrf-map/1", "landmarks": [{}, {}, {}]}}"#,
            lm(1, 0.0, 0.0),
            lm(1, 2.0, 0.0),
            lm(3, 0.0, 2.0)
        ),
    );
    let few = w(
        "few.json",
        &format!(
            r#"{{"format": "odocal.lrf-map/1", "landmarks": [{}, {}]}}"#,
            lm(1, 0.0, 0.0),
            lm(2, 2.0, 0.0)
        ),
    );
    let wrong = w("wrong.json", r#"{"format": "odocal.camera/1"}"#);
    let scan = w(
        "scan.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.01,1.0,0.1\n0.02,1.0,0.1\n",
    );
    let nan = w(
        "nan.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.01,1.0,NaN\n",
    );
    let neg = w(
        "neg.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.01,-0.5,0.1\n",
    );
    let uneven = w(
        "uneven.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.01,1.0,0.1\n0.025,1.0,0.1\n",
    );
    let other_step = w(
        "other.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.02,1.0,0.1\n0.04,1.0,0.1\n",
    );
    let out = d.join("p.csv");
    let loc = |map: &Path, scans: &Path| -> Vec<String> {
        [
            "lrf",
            "localize",
            "--map",
            s(map),
            s(scans),
            "--out",
            s(&out),
        ]
        .iter()
        .map(|x| x.to_string())
        .collect()
    };
    let run = |v: Vec<String>, want: &str| {
        expect_error(&v.iter().map(|x| x.as_str()).collect::<Vec<_>>(), want)
    };
    run(loc(&dup, &scan), "share id 1");
    run(loc(&few, &scan), "at least 3 are needed");
    run(loc(&wrong, &scan), "expected \"odocal.lrf-map/1\"");
    run(loc(&good, &nan), "nan.csv, line 3, column intensity");
    run(
        loc(&good, &neg),
        "neg.csv, line 3, column range: range is -0.5",
    );
    run(
        loc(&good, &uneven),
        "uneven.csv, line 4, column angle: mismatched angle step",
    );
    let mut v = loc(&good, &scan);
    v.push(s(&other_step).to_string());
    run(v, "mismatched angle steps");
    expect_error(&["lrf", "check-map", s(&dup)], "share id 1");
    expect_error(
        &["lrf", "check-map", s(&d.join("missing.json"))],
        "cannot read",
    );
    // The good inputs are read, but three flat beams show no reflector, none as bright as
    // --intensity-min: said so, not blamed on the map.
    run(
        loc(&good, &scan),
        "no return of the scans reaches --intensity-min 0.5 (median return 0.1",
    );
    // With one bright beam there is a detection but no pose: a file of nothing but lost
    // scans is refused, not written.
    let glint = w(
        "glint.csv",
        "angle,range,intensity\n0.0,1.0,0.1\n0.01,1.0,0.9\n0.02,1.0,0.1\n",
    );
    run(loc(&good, &glint), "none of the 1 scan found a pose");
}

/// Scan files as other tools write them: a header in capitals (`Scan,T,Angle,Range,
/// Intensity`) was refused, and so was NaN for a beam without a return (ROS's REP 117), with
/// "use 0". Read by name in any order and case, with NaN as no return, they give the poses of
/// the file as `synth lrf` wrote it, byte for byte.
#[test]
fn cli_scan_headers_in_any_case_and_nan_ranges_are_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 8);
    let (_, rows) = scan_rows(d);
    assert!(
        rows.iter().any(|r| r[3].parse::<f64>() == Ok(0.0)),
        "no beam without a return"
    );
    let other = rewrite_scans(
        &d.join("other.csv"),
        "Intensity,Range,Angle,T,Scan",
        &rows,
        &|scan| {
            scan.iter()
                .map(|r| {
                    let range = if r[3].parse::<f64>() == Ok(0.0) {
                        "NaN"
                    } else {
                        &r[3]
                    };
                    format!("{},{range},{},{},{}", r[4], r[2], r[1], r[0])
                })
                .collect()
        },
    );
    let plain = localize(d, &[]);
    assert!(
        plain.status.success(),
        "{}",
        String::from_utf8_lossy(&plain.stderr)
    );
    let want = std::fs::read_to_string(d.join("poses.csv")).expect("poses");
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&d.join("map.json")),
        s(&other),
        "--out",
        s(&d.join("other_poses.csv")),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(d.join("other_poses.csv")).expect("poses"),
        want
    );
}

/// Scan 272 of `synth lrf --landmarks 200 --seed 2` sees two real reflectors and a glint; the
/// three happen to fit three other landmarks 1.77 m away. Neither mode may call that pose `ok`:
/// a lone match of three detections in a 200-landmark map is not proof (the odds of such a
/// coincidence are checked), the three do not fit those landmarks within their own
/// covariances (the weighted fit's residuals are checked; each check refutes the pose on its
/// own), and in tracking mode a global pose far from the confirmed track is a jump that the
/// next scans must confirm (checked on its own with both other checks off).
#[test]
fn a_glint_matching_the_wrong_landmarks_is_never_a_confident_pose() {
    let sim = simulate(&LrfSimConfig::scaled(200, 2));
    let map = Map::parse(&sim.map_json(), "sim").expect("simulated map is valid");
    let scans = scans_of(&sim);
    let truth = truth_of(&sim);
    let is_wrong_ok = |status: Status, pose: Option<odocal_core::Pose2>, k: usize| {
        status == Status::Ok
            && pose.is_some_and(|p| (p.position() - truth.poses()[k].pose.position()).norm() > 0.05)
    };
    let strict = Localizer::new(map.clone(), LocalizerConfig::default());
    let d = strict.detections(&scans[272]);
    assert_eq!(d.len(), 3, "the scan of the glint case");
    let g = strict.global(&scans[272], &d);
    assert_ne!(g.status, Status::Ok, "global: {:?}", g.best());
    let with = |max_chance_ok: f64, max_residual_sigmas: f64| {
        Localizer::new(
            map.clone(),
            LocalizerConfig {
                max_chance_ok,
                max_residual_sigmas,
                ..LocalizerConfig::default()
            },
        )
    };
    let inf = f64::INFINITY;
    for (one_check, on) in [(with(inf, 4.0), "residuals"), (with(1.0, inf), "odds")] {
        let g = one_check.global(&scans[272], &d);
        assert_ne!(g.status, Status::Ok, "{on} check alone: {:?}", g.best());
    }
    let lax = with(inf, inf);
    let g = lax.global(&scans[272], &d);
    assert!(
        is_wrong_ok(g.status, g.best().map(|h| h.pose), 272),
        "without the odds and residual checks the glint case is a confident wrong pose (so the test bites)"
    );
    for loc in [&strict, &lax] {
        let rows = track(loc, &scans);
        let wrong: Vec<usize> = (0..rows.len())
            .filter(|&k| is_wrong_ok(rows[k].status, rows[k].pose, k))
            .collect();
        assert!(wrong.is_empty(), "confident wrong poses at scans {wrong:?}");
        let e = evaluate(&rows, &truth);
        assert!(
            e.n_correct_eligible as f64 >= 0.98 * e.n_eligible as f64,
            "correct on {}/{}",
            e.n_correct_eligible,
            e.n_eligible
        );
    }
}

/// Scans in the wrong unit or orientation: angles in degrees and ranges in millimetres are
/// refused with the unit named (degrees gave 15 confident wrong poses, millimetres every scan
/// lost, both with exit 0); a mirrored scanner (mounted upside down) loses most scans, its
/// scans mirrored find poses, and it is refused with --upside-down named.
#[test]
fn cli_scans_in_the_wrong_unit_or_mirrored_are_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // Beams cast from each scan's pose, so the mirrored ones are the same returns.
    synth_lrf_with(d, 4, 40, &["--sweep-s", "0"]);
    let (header, rows) = scan_rows(d);
    let write = |name: &str, f: &dyn Fn(&[String]) -> Vec<String>, reverse: bool| {
        rewrite_scans(&d.join(name), &header, &rows, &|scan| {
            let mut lines: Vec<String> = scan.iter().map(|r| f(r).join(",")).collect();
            if reverse {
                lines.reverse();
            }
            lines
        })
    };
    let num = |v: &str| v.parse::<f64>().expect("number");
    let degrees = write(
        "degrees.csv",
        &|r| {
            let mut r = r.to_vec();
            r[2] = format!("{:.5}", num(&r[2]).to_degrees());
            r
        },
        false,
    );
    let millimetres = write(
        "mm.csv",
        &|r| {
            let mut r = r.to_vec();
            r[3] = format!("{:.1}", num(&r[3]) * 1000.0);
            r
        },
        false,
    );
    let centimetres = write(
        "cm.csv",
        &|r| {
            let mut r = r.to_vec();
            r[3] = format!("{:.2}", num(&r[3]) * 100.0);
            r
        },
        false,
    );
    let byte_scale = write(
        "i255.csv",
        &|r| {
            let mut r = r.to_vec();
            r[4] = format!("{}", (num(&r[4]) * 255.0).round());
            r
        },
        false,
    );
    let mirrored = write(
        "mirrored.csv",
        &|r| {
            let mut r = r.to_vec();
            r[2] = format!("{}", -num(&r[2]));
            r
        },
        true,
    );
    let map = d.join("map.json");
    let poses = d.join("poses.csv");
    let args = |scans: &Path| {
        vec![
            "lrf".to_string(),
            "localize".into(),
            "--map".into(),
            s(&map).into(),
            s(scans).into(),
            "--out".into(),
            s(&poses).into(),
            "--sweep-s".into(),
            "0".into(),
        ]
    };
    let run = |scans: &Path| {
        let a = args(scans);
        odocal(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let a = args(&degrees);
    expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "scan 0's angles run from -119.88281 to -113.20313, beyond a full turn; angles are in radians (if they are in degrees, -119.88281° to -113.20313° is -2.0923 to -1.9758 rad)",
    );
    let a = args(&millimetres);
    expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "ranges are in metres (if these are millimetres",
    );
    // In centimetres the advice used to say millimetres, with the median in raw digits.
    let a = args(&centimetres);
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "ranges are in metres (if these are centimetres",
    );
    assert!(
        e.split("median range is ")
            .nth(1)
            .and_then(|rest| rest.split(' ').next())
            .is_some_and(|median| median.split('.').nth(1).is_some_and(|d| d.len() == 3)),
        "{e}"
    );
    // Intensities on a 0-255 scale against the default 0.5: every wall passes for a
    // reflector. Refused with a threshold on their scale, which then localises as the 0-1
    // intensities do.
    let a = args(&byte_scale);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    expect_error(
        &a,
        "100 % of the scans' returns are at or above --intensity-min 0.5",
    );
    let err = String::from_utf8_lossy(&odocal(&a).stderr).into_owned();
    let suggested = err
        .trim_end()
        .rsplit("halfway between those two: ")
        .next()
        .and_then(|v| v.strip_suffix(')'))
        .expect("a suggested threshold")
        .to_string();
    let mut a = args(&byte_scale);
    a.extend(["--intensity-min".into(), suggested.clone()]);
    let out = odocal(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let plain = run(&d.join("scans.csv"));
    assert!(
        out.status.success(),
        "{suggested}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // "lrf localize: 40 scans (tracking mode): N ok, N ambiguous, N lost": the same counts.
    let summary = |o: &std::process::Output| {
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let line = text.lines().find(|l| l.starts_with("lrf localize:"));
        line.and_then(|l| l.split(';').next())
            .map(str::to_string)
            .expect("a summary")
    };
    assert_eq!(
        summary(&out),
        summary(&plain),
        "--intensity-min {suggested}"
    );
    assert!(summary(&plain).contains(" ok,"), "{}", summary(&plain));
    std::fs::remove_file(&poses).expect("poses written");
    // A threshold above every return: no scan can find a pose, which was blamed on the map
    // ("none of the 40 scans found a pose … is map.json the map of this room"); the
    // threshold is named, with one on the scans' scale, which localises as they do.
    let mut a = args(&d.join("scans.csv"));
    a.extend(["--intensity-min".into(), "2".into()]);
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "no return of the scans reaches --intensity-min 2 (median return ",
    );
    assert!(!e.contains("map of this room"), "{e}");
    let suggested = e
        .trim_end()
        .rsplit("halfway between the median and the brightest 1 %: ")
        .next()
        .and_then(|v| v.strip_suffix(')'))
        .expect("a suggested threshold")
        .to_string();
    assert!((0.5..1.0).contains(&num(&suggested)), "{e}");
    let mut a = args(&d.join("scans.csv"));
    a.extend(["--intensity-min".into(), suggested.clone()]);
    let out = odocal(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(
        summary(&out),
        summary(&plain),
        "--intensity-min {suggested}"
    );
    std::fs::remove_file(&poses).expect("poses written");
    // Every intensity 0 (a scanner that records none): asked whether it does.
    let zero = write(
        "zero.csv",
        &|r| {
            let mut r = r.to_vec();
            r[4] = "0".into();
            r
        },
        false,
    );
    let a = args(&zero);
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "returns is 0, so no return reaches --intensity-min 0.5 and no reflector can be told from a wall: does the scanner record intensity?",
    );
    assert!(e.contains("every intensity of the scans' "), "{e}");
    // Range and intensity swapped: the scale's refusal asked for --intensity-min 4.05, a
    // typical range.
    let swapped = write(
        "swapped.csv",
        &|r| {
            let mut r = r.to_vec();
            r.swap(3, 4);
            r
        },
        false,
    );
    let a = args(&swapped);
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "are the range and intensity columns swapped? Put the ranges (metres) under the header's `range`",
    );
    assert!(e.contains("every range of the scans lies within 0."), "{e}");
    assert!(!e.contains("--intensity-min"), "{e}");
    assert!(!poses.exists(), "nothing written on refusal");
    // Mirrored, most scans are lost and the few poses found were coincidences (one `ok`
    // 4.2 m off with a σ of 3 mm was written as ground truth): refused, naming the mounting;
    // with --upside-down the same scans give the poses of the scans as they were.
    let a = args(&mirrored);
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "scans found no pose, and with their angles mirrored ",
    );
    assert!(
        e.contains("the scanner looks mounted upside down, its angles clockwise, so nothing was written; give --upside-down"),
        "{e}"
    );
    // A map with its y axis flipped fits the scans the same way: it is named too.
    assert!(
        e.contains("or, if the scanner is the right way up, the map is a mirror image of the room (its y axis flipped, a left-handed frame)"),
        "{e}"
    );
    assert!(!poses.exists(), "nothing written on refusal");
    let mut a = args(&mirrored);
    a.push("--upside-down".into());
    let out = odocal(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(summary(&out), summary(&plain));
    // Scans the right way up given --upside-down are named the other way round.
    let mut a = args(&d.join("scans.csv"));
    a.push("--upside-down".into());
    let e = expect_error(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        "the scanner looks mounted the right way up",
    );
    assert!(e.trim_end().ends_with("drop --upside-down"), "{e}");
    // The scans as they are: no warning.
    let out = run(&d.join("scans.csv"));
    assert!(out.status.success());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
}

/// Error/σ of the poses of a trajectory written by `lrf localize --trajectory` against `synth
/// lrf`'s truth: the RMS in position (x, y), in heading, and the largest of a row on any axis
/// with that row's time.
fn error_over_sigma(traj: &Path, truth: &Path) -> (f64, f64, f64, f64) {
    let truth = std::fs::read_to_string(truth).expect("truth");
    let truth: Vec<(f64, f64, f64, f64)> = truth
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .take(4)
                .map(|x| x.parse().expect("number"))
                .collect();
            (v[0], v[1], v[2], v[3])
        })
        .collect();
    let t = odocal_core::Trajectory::read_csv(traj).expect("a trajectory");
    let (mut z2, mut h2, mut worst) = (0.0, 0.0, (0.0f64, 0.0));
    for r in &t.rows {
        let (_, x, y, th) = truth
            .iter()
            .find(|(tt, ..)| (tt - r.t_s).abs() < 1e-3)
            .expect("a truth row at the scan's time");
        let sigma = r.sigma.expect("σ on every row");
        let z = [
            (r.pose.x_m - x) / sigma.x_m,
            (r.pose.y_m - y) / sigma.y_m,
            odocal_core::wrap_angle(r.pose.theta_rad - th) / sigma.theta_rad,
        ];
        z2 += z[0].powi(2) + z[1].powi(2);
        h2 += z[2].powi(2);
        let row = z.iter().fold(0.0f64, |w, v| w.max(v.abs()));
        if row > worst.0 {
            worst = (row, r.t_s);
        }
    }
    let n = t.rows.len().max(1) as f64;
    ((z2 / (2.0 * n)).sqrt(), (h2 / n).sqrt(), worst.0, worst.1)
}

/// The laser's `ok` poses as a trajectory (`--trajectory`): one row per `ok` scan, in the
/// format `dataset` and `evaluate` read, with σ that the errors against the truth bear out.
/// `synth lrf` sweeps its beams over 67 ms as a 10 Hz scanner's mirror turns while the sensor
/// drives 0.5 m/s and turns up to 12°/s; `lrf localize` de-skews them with the tracked motion.
/// Cast as if from the first beam's pose (`--sweep-s 0`) the poses were 5–12 times further
/// from the truth than their σ, with no word; `--global-only`, which tracks no motion, widens
/// the σ by half a sweep's motion and says so.
#[test]
fn cli_laser_poses_as_a_trajectory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 4, 120);
    // The ok count, error/σ RMS in position (x, y) and heading of the trajectory written, and
    // the largest error/σ of a row.
    let run = |name: &str, extra: &[&str]| -> (usize, f64, f64, f64, String) {
        let traj = d.join(format!("{name}.csv"));
        let mut args = vec!["--trajectory", s(&traj)];
        args.extend_from_slice(extra);
        let out = localize_into(d, &d.join(format!("{name}.poses.csv")), &args);
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        assert!(stdout.contains(&format!("and {}", s(&traj))), "{stdout}");
        let n_ok: usize = stdout
            .split(" ok,")
            .next()
            .and_then(|l| l.rsplit(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no ok count: {stdout}"));
        let t = odocal_core::Trajectory::read_csv(&traj).expect("a trajectory");
        assert_eq!(t.rows.len(), n_ok);
        let (z, h, worst, _) = error_over_sigma(&traj, &d.join("truth.csv"));
        println!(
            "{name}: {n_ok} poses, error/σ RMS {z:.2} (x, y), {h:.2} (heading), worst {worst:.1}"
        );
        (n_ok, z, h, worst, stderr)
    };
    let (n_ok, z, h, worst, stderr) = run("deskewed", &[]);
    assert!(n_ok >= 100, "{n_ok} ok");
    assert!((0.6..=1.6).contains(&z), "error/σ RMS {z:.2}");
    assert!((0.6..=1.3).contains(&h), "heading error/σ RMS {h:.2}");
    // The first de-skewed pose of the track was 8.3σ off, de-skewed with the motion from a
    // pose left with its sweep's skew.
    assert!(worst <= 3.5, "a pose {worst:.1}σ off");
    assert!(!stderr.contains("de-skewed"), "{stderr}");
    // The poses that fit their landmarks worst, or lie off the track, have their σ widened,
    // which covers a part of the skew (error/σ 2.8 where it was 3.6), not all of it.
    let (_, z, h, _, _) = run("skewed", &["--sweep-s", "0"]);
    assert!(z > 2.5 && h > 4.0, "error/σ RMS {z:.2}, heading {h:.2}");
    let (n_ok, z, h, _, stderr) = run("global", &["--global-only"]);
    assert!(n_ok >= 100, "{n_ok} ok");
    assert!(z <= 1.6 && h <= 1.6, "error/σ RMS {z:.2}, heading {h:.2}");
    assert!(
        stderr.contains("poses were not de-skewed and the sensor moved up to")
            && stderr.contains("drop it to de-skew them"),
        "{stderr}"
    );
    // A single scan has no motion to de-skew it by, nor a neighbour to widen its σ by: its
    // heading was 22 times its σ off in silence.
    let (header, rows) = scan_rows(d);
    let one = rewrite_scans(&d.join("one.csv"), &header, &rows, &|scan| {
        if scan[0][0] == rows[0][0] {
            scan.iter().map(|r| r.join(",")).collect()
        } else {
            Vec::new()
        }
    });
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&d.join("map.json")),
        s(&one),
        "--out",
        s(&d.join("one.poses.csv")),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("1 of 1 poses could not be de-skewed and have no pose beside them"),
        "{stderr}"
    );
}

/// The `ok` count and the position RMS, mm, that `lrf localize --truth` prints.
fn ok_and_rms(out: &std::process::Output) -> (usize, f64) {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let ok = text
        .split(" ok,")
        .next()
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok());
    let rms = text
        .split("position RMS ")
        .nth(1)
        .and_then(|l| l.split(" mm").next())
        .and_then(|v| v.parse().ok());
    match (ok, rms) {
        (Some(ok), Some(rms)) => (ok, rms),
        _ => panic!("no ok count or RMS in {text}"),
    }
}

/// Wall beams without a return (range 0, inf as ROS drivers write it, or the maximum range
/// as Gazebo and many drivers write it, or a 16-bit sentinel of 65.535), scattered or over a
/// whole sector as a glass door or a black cabinet leaves them, do not cost a scan its fix:
/// the reflectors are all still there. Every scan stays `ok`, as accurate as before, and no
/// warning blames the map. A scanner of a wider view whose outer beams return nothing (the
/// rear of a 360° scanner masked by the robot: the same scans padded with `inf` beams, 15°
/// or 59° each side) gives the very same poses. The landmarks behind the mask used to count
/// as missed (scan 1 here scored 5 instead of 6; `synth lrf --scans 100` padded by 59° gave 58
/// ok and 42 ambiguous scans against 99 and 1).
#[test]
fn cli_beams_without_a_return_keep_the_fix() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // Beams taken at once, as these scans are read (`--sweep-s 0`): swept beams read so
    // bias the landmarks by the robot's motion, which is named as a moved landmark.
    synth_lrf_with(d, 2, 30, &["--sweep-s", "0"]);
    let (header, rows) = scan_rows(d);
    let num = |v: &str| v.parse::<f64>().expect("number");
    let write = |name: &str, no_return: &dyn Fn(usize, &[String]) -> Option<&'static str>| {
        let mut out = vec![header.to_string()];
        let mut n = 0;
        for (i, r) in rows.iter().enumerate() {
            let mut r = r.clone();
            // Only wall returns lose their echo; reflectors stay bright.
            if num(&r[4]) < 0.5 {
                if let Some(v) = no_return(i, &r) {
                    r[3] = v.to_string();
                    n += 1;
                }
            }
            out.push(r.join(","));
        }
        let p = d.join(name);
        std::fs::write(&p, out.join("\n") + "\n").expect("write");
        (p, n)
    };
    // Every tenth wall row, a deterministic 10 %.
    let (zero, n_zero) = write("zero.csv", &|i, _| (i % 10 == 3).then_some("0"));
    let (inf, _) = write("inf.csv", &|i, _| (i % 10 == 3).then_some("inf"));
    // Read as returns through the walls, these lost 198 and 282 of 300 scans.
    let (rmax, _) = write("rmax.csv", &|i, _| (i % 10 == 3).then_some("5.6"));
    let (sentinel, _) = write("sentinel.csv", &|i, _| (i % 10 == 3).then_some("65.535"));
    let sector = (0.3, 0.3 + 17f64.to_radians());
    let (dark, n_dark) = write("sector.csv", &|_, r| {
        let a = num(&r[2]);
        (sector.0..sector.1).contains(&a).then_some("0")
    });
    assert!(n_zero > 1500 && n_dark > 1000, "{n_zero} {n_dark}");
    let pad = |name: &str, deg: f64| {
        rewrite_scans(&d.join(name), &header, &rows, &|scan| {
            let (a0, a1) = (num(&scan[0][2]), num(&scan[scan.len() - 1][2]));
            let step = num(&scan[1][2]) - a0;
            let n = (deg.to_radians() / step) as i32;
            let blank = |a: f64| format!("{},{},{a:.7},inf,0", scan[0][0], scan[0][1]);
            let mut lines: Vec<String> =
                (1..=n).rev().map(|i| blank(a0 - step * i as f64)).collect();
            lines.extend(scan.iter().map(|r| r.join(",")));
            lines.extend((1..=n).map(|i| blank(a1 + step * i as f64)));
            lines
        })
    };
    let (pad15, pad59) = (pad("pad15.csv", 15.0), pad("pad59.csv", 59.0));
    let truth = d.join("truth.csv");
    let map = d.join("map.json");
    let poses = d.join("poses.csv");
    let run = |scans: &Path, fov_deg: &str| {
        let out = odocal(&[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(scans),
            "--out",
            s(&poses),
            "--truth",
            s(&truth),
            "--fov-deg",
            fov_deg,
            // Padding puts other beams first: beam times would differ with the sweep.
            "--sweep-s",
            "0",
        ]);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{}: {err}", s(scans));
        assert!(!err.contains("warning"), "{}: {err}", s(scans));
        let written = std::fs::read_to_string(&poses).expect("poses written");
        std::fs::remove_file(&poses).expect("poses written");
        (ok_and_rms(&out), written)
    };
    let ((ok0, rms0), poses0) = run(&d.join("scans.csv"), "240");
    assert_eq!(ok0, 30);
    for (scans, fov_deg) in [(&pad15, "270"), (&pad59, "358")] {
        let ((ok, rms), written) = run(scans, fov_deg);
        println!(
            "{} (--fov-deg {fov_deg}): {ok}/30 ok, position RMS {rms:.1} mm",
            s(scans)
        );
        // The same rows; the poses within 0.1 mm and 0.0001 rad (the padded scans' step,
        // from angles written to 7 decimals, differs in its last digits).
        let (a, b): (Vec<&str>, Vec<&str>) = (written.lines().collect(), poses0.lines().collect());
        assert_eq!((a.len(), a[0]), (b.len(), b[0]), "{}", s(scans));
        for (ra, rb) in a.iter().zip(&b).skip(1) {
            let (fa, fb): (Vec<&str>, Vec<&str>) =
                (ra.split(',').collect(), rb.split(',').collect());
            let near = (1..4).all(|k| (num(fa[k]) - num(fb[k])).abs() <= 1.5e-5);
            assert!(
                near && fa[4..] == fb[4..],
                "{}: {ra} where the unpadded scans give {rb}",
                s(scans)
            );
        }
    }
    for scans in [&zero, &inf, &rmax, &sentinel, &dark] {
        let ((ok, rms), _) = run(scans, "240");
        println!(
            "{}: {ok}/30 ok, position RMS {rms:.1} mm (unmodified: {ok0}/30 ok, {rms0:.1} mm)",
            s(scans)
        );
        assert_eq!(ok, ok0, "{}", s(scans));
        assert!(
            rms <= 1.1 * rms0,
            "{}: {rms} mm against {rms0} mm",
            s(scans)
        );
    }
}

/// The angles of a scan file are explicit, so a scan is read whichever way its beams are
/// listed and wherever its turn starts: beams in decreasing angle order (a ROS scan with a
/// negative angle_increment, once refused with "angles must increase") give the very poses of
/// the original, with one note for all the scans, and the same returns as a 360° scan from
/// π/2 to 5π/2 (once blamed on degrees) give them within the angles' 7 decimals.
#[test]
fn cli_scans_listed_left_to_right_or_from_anywhere_are_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // Beams taken at once, as these scans are read (`--sweep-s 0`): swept beams read so
    // bias the landmarks by the robot's motion, which is named as a moved landmark.
    synth_lrf_with(d, 4, 20, &["--sweep-s", "0"]);
    let (header, rows) = scan_rows(d);
    let num = |v: &str| v.parse::<f64>().expect("number");
    let reversed = rewrite_scans(&d.join("reversed.csv"), &header, &rows, &|scan| {
        scan.iter().rev().map(|r| r.join(",")).collect()
    });
    let turn = rewrite_scans(&d.join("turn.csv"), &header, &rows, &|scan| {
        let (a0, step) = (num(&scan[0][2]), num(&scan[1][2]) - num(&scan[0][2]));
        let n = (std::f64::consts::TAU / step).round() as i64;
        let k0 = ((std::f64::consts::FRAC_PI_2 - a0) / step).round() as i64;
        (k0..k0 + n)
            .map(|k| {
                let a = a0 + k as f64 * step;
                match scan.get(k.rem_euclid(n) as usize) {
                    Some(r) => format!("{},{},{a:.7},{},{}", r[0], r[1], r[3], r[4]),
                    None => format!("{},{},{a:.7},inf,0", scan[0][0], scan[0][1]),
                }
            })
            .collect()
    });
    let poses = |scans: &Path, name: &str| {
        let out = d.join(name);
        let (map, truth) = (d.join("map.json"), d.join("truth.csv"));
        // The beams taken all at once: listed in reverse, a sweep would be a clockwise one.
        let run = odocal(&[
            "lrf",
            "localize",
            "--sweep-s",
            "0",
            "--map",
            s(&map),
            s(scans),
            "--out",
            s(&out),
            "--truth",
            s(&truth),
            "--fov-deg",
            "360",
        ]);
        let err = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(run.status.success(), "{}: {err}", s(scans));
        let text = std::fs::read_to_string(&out).expect("poses written");
        (text, err)
    };
    let (original, err) = poses(&d.join("scans.csv"), "original.csv");
    assert!(!err.contains("note"), "{err}");
    let (from_reversed, err) = poses(&reversed, "reversed_poses.csv");
    assert_eq!(from_reversed, original);
    assert_eq!(err.matches("note:").count(), 1, "{err}");
    assert!(
        err.contains("note: 20 of the 20 scans (the first in ")
            && err.contains("list their beams in decreasing angle order (a negative angle_increment); they were read in increasing order"),
        "{err}"
    );
    let (from_turn, err) = poses(&turn, "turn_poses.csv");
    assert!(!err.contains("note") && !err.contains("warning"), "{err}");
    let (a, b): (Vec<&str>, Vec<&str>) = (from_turn.lines().collect(), original.lines().collect());
    assert_eq!((a.len(), a[0]), (b.len(), b[0]));
    for (ra, rb) in a.iter().zip(&b).skip(1) {
        let (fa, fb): (Vec<&str>, Vec<&str>) = (ra.split(',').collect(), rb.split(',').collect());
        let near = (1..4).all(|k| (num(fa[k]) - num(fb[k])).abs() <= 1.5e-4);
        assert!(
            near && fa[4..6] == fb[4..6],
            "{ra} from π/2 where the original gives {rb}"
        );
    }
}

/// A symmetric layout where every scan fits two places: not one scan is `ok`, so there is no
/// result to write and no error to report. Refused like scans that find no pose at all, with
/// the layout named as the cause and what to do, rather than a header-only trajectory and a
/// "position RMS 0.0 mm over 0 ok scans". (16 landmarks: 8 pairs leave every scan of this
/// path two places to be.)
#[test]
fn cli_no_ok_scan_in_a_symmetric_layout_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    assert!(odocal(&[
        "synth",
        "lrf",
        "--out",
        s(d),
        "--symmetric",
        "--landmarks",
        "16",
        "--scans",
        "30",
        // The figures below are of beams cast from each scan's pose.
        "--sweep-s",
        "0"
    ])
    .status
    .success());
    let (poses, traj) = (d.join("poses.csv"), d.join("traj.csv"));
    let truth = d.join("truth.csv");
    let args = [
        "--trajectory",
        s(&traj),
        "--truth",
        s(&truth),
        "--sweep-s",
        "0",
    ];
    let out = localize(d, &args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stdout.contains("RMS"), "{stdout}");
    let map = d.join("map.json");
    let mut all = vec!["lrf", "localize", "--map", s(&map)];
    let scans = d.join("scans.csv");
    all.extend([s(&scans), "--out", s(&poses)]);
    all.extend(args);
    expect_error(
        &all,
        "none of the 30 scans found a pose it could tell from another (30 ambiguous, 0 lost",
    );
    expect_error(&all, "(a symmetric layout)");
    expect_error(
        &all,
        &format!(
            "run `odocal lrf check-map {}` and add or move a landmark",
            s(&map)
        ),
    );
    assert!(!poses.exists() && !traj.exists(), "nothing written");
    // One landmark of a pair left out of the map: the scans that see its partner are told
    // apart (and tracked on), the others stay ambiguous, and the poses written leave them
    // out. That is said, not left to be found in the poses' status column.
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).expect("map")).expect("json");
    m["landmarks"]
        .as_array_mut()
        .expect("landmarks")
        .retain(|l| l["id"] != 10);
    let broken = d.join("map2.json");
    std::fs::write(&broken, m.to_string()).expect("write");
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&broken),
        s(&scans),
        "--out",
        s(&poses),
        "--truth",
        s(&truth),
        "--sweep-s",
        "0",
    ]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("22 ok, 8 ambiguous, 0 lost"), "{stdout}");
    assert!(stdout.contains("confident wrong poses: 0;"), "{stdout}");
    assert!(
        stderr.contains("warning: 8 of 30 scans fit the map in several places and have no pose")
            && stderr.contains("(a symmetric layout)"),
        "{stderr}"
    );
}

/// A symmetric room whose map has one more reflector, one that is gone from the room (fallen
/// off, covered): the only evidence between a pose and its mirror image is that reflector,
/// in view of the right pose and never seen. That is no proof (reflectors are missed now and
/// then), so the scans stay ambiguous, and the reflector is named. The missed reflector alone
/// used to make 143 `ok` poses, every one the mirror pose 4.4–6.3 m off.
#[test]
fn cli_a_mapped_reflector_gone_from_a_symmetric_room_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 1, 150, &["--symmetric"]);
    let map = d.join("map.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).expect("map")).expect("json");
    m["landmarks"].as_array_mut().expect("landmarks").push(
        serde_json::json!({"id": 31, "x_m": 9.998, "y_m": 4.3, "facing_rad": std::f64::consts::PI,
            "visibility_line": {"visible": "left", "x_m": 9.998}}),
    );
    let plus = d.join("map_plus1.json");
    std::fs::write(&plus, m.to_string()).expect("write");
    let (scans, poses) = (d.join("scans.csv"), d.join("poses.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&plus),
        s(&scans),
        "--out",
        s(&poses),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "warning: landmark 31 of {} was in view in 26 scans and not seen in 25 of them: is it still there?",
            s(&plus)
        )) && stderr.contains(
            "odocal: error: none of the 150 scans found a pose it could tell from another (150 ambiguous, 0 lost"
        ),
        "{stderr}"
    );
    // The refusal names the gone reflector as the cause, as the warning does, rather than
    // advising to add a landmark beside it.
    assert!(
        stderr.contains(&format!(
            "nothing was written: landmark 31 at (10.00, 4.30) m of {} was not seen in 25 of the 26 scans it should have been in view in; with it gone the landmarks repeat themselves (a symmetric layout); put it back, or remove it from the map and add one that breaks the symmetry",
            s(&plus)
        )) && !stderr.contains("add or move a landmark"),
        "{stderr}"
    );
    // Not one landmark of the room as mapped is named.
    assert_eq!(stderr.matches("warning: landmark").count(), 1, "{stderr}");
}

/// Five of the thirty reflectors re-stuck 5 cm along their walls after mapping, the map (a
/// survey's 5 mm σ) not updated: each is named with its offset, and the scans are localised
/// again without them. Landmarks 8 and 14, 0.31 m apart, moved together and passed every
/// scan's match screen; unnamed, they left poses 40 mm (10σ) off with exit 0. Named, but with
/// only the poses that matched them fitted again from the same matches, poses stayed up to
/// 37.6 mm (7.3σ) off: the pair had steered the tracking (the good landmarks beside them
/// dropped as outliers, the motion the sweeps were de-skewed with). The same map unmoved names
/// none.
/// A robot whose turn rate changes (10°/s² on seed 2, t = 12–16 s) left its poses 4–6σ off
/// in heading for a second at a time (heading error/σ RMS 1.34 over the track, worst 6.2):
/// each sweep was de-skewed with the turn rate from the pose before to the scan's own fit,
/// half a scan period late and pulled by that fit's own error. With the turn rate between
/// the neighbours, every pose is within 4σ and the heading's σ is right.
#[test]
fn cli_a_changing_turn_rate_leaves_no_pose_off_its_sigma() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 2, 300, &[]);
    let (traj, truth) = (d.join("traj.csv"), d.join("truth.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&d.join("map.json")),
        s(&d.join("scans.csv")),
        "--out",
        s(&d.join("poses.csv")),
        "--trajectory",
        s(&traj),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (z, h, worst, at) = error_over_sigma(&traj, &truth);
    println!("error/σ RMS {z:.2} (x, y), {h:.2} (heading), worst {worst:.1} at t = {at} s");
    assert!(
        (0.7..=1.15).contains(&z) && (0.8..=1.15).contains(&h),
        "error/σ RMS {z:.2}, heading {h:.2}"
    );
    assert!(worst <= 4.0, "the pose at t = {at} s is {worst:.1}σ off");
}

#[test]
fn cli_reflectors_moved_after_mapping_are_named_and_left_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 3, 300, &[]);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    m["position_sigma_m"] = serde_json::json!(0.005);
    let surveyed = d.join("map_surveyed.json");
    std::fs::write(&surveyed, m.to_string()).expect("write");
    for l in m["landmarks"].as_array_mut().expect("landmarks") {
        if [3, 8, 14, 21, 27].contains(&l["id"].as_u64().expect("id")) {
            let f = l["facing_rad"].as_f64().expect("facing");
            let (x, y) = (l["x_m"].as_f64().expect("x"), l["y_m"].as_f64().expect("y"));
            l["x_m"] = serde_json::json!(x - 0.05 * f.sin());
            l["y_m"] = serde_json::json!(y + 0.05 * f.cos());
        }
    }
    let moved = d.join("map_moved.json");
    std::fs::write(&moved, m.to_string()).expect("write");
    let (scans, poses, truth, traj) = (
        d.join("scans.csv"),
        d.join("poses.csv"),
        d.join("truth.csv"),
        d.join("traj.csv"),
    );
    let run = |map: &Path| {
        let out = localize_judged(map, &scans, &poses, &traj, &truth);
        (
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let (stdout, stderr) = run(&moved);
    assert!(
        stderr.contains(&format!(
            "warning: landmark 8 of {} sits 44 mm from its mapped position along (0.01, -1.00) in 53 scans from 53 places (σ of that mean 1.5 mm): was it moved after mapping? Every scan was localised again with the map without it",
            s(&moved)
        )),
        "{stderr}"
    );
    for id in [3, 14, 21, 27] {
        assert!(
            stderr.contains(&format!("warning: landmark {id} of {} sits ", s(&moved))),
            "{stderr}"
        );
    }
    assert_eq!(stderr.matches("warning: landmark").count(), 5, "{stderr}");
    // Every pose is as good as its σ says, over the whole track.
    assert!(stdout.contains("297 ok, 0 ambiguous, 3 lost"), "{stdout}");
    assert!(
        stdout.contains("position RMS 4.4 mm (Cramér–Rao bound 7.0 mm, ratio 0.63), max 19.5 mm"),
        "{stdout}"
    );
    let (z, h, worst, at) = error_over_sigma(&traj, &truth);
    assert!(z <= 1.2 && h <= 1.2, "error/σ RMS {z:.2}, heading {h:.2}");
    assert!(worst <= 4.0, "the pose at t = {at} s is {worst:.1}σ off");
    let (_, stderr) = run(&surveyed);
    assert!(!stderr.contains("warning: landmark"), "{stderr}");
}

/// A robot standing still, scanned again and again with fresh noise: its scans share the
/// viewpoint, and with it which beams hit each strip, so their errors do not average away
/// scan by scan. The moved-landmark check took the scans for independent and told a correct
/// map to be edited ("landmark N sits 14 mm from its mapped position … in 97 scans (σ of that
/// mean 0.5 mm): was it moved after mapping?"). Landmarks really moved are still named
/// (`cli_reflectors_moved_after_mapping_are_named_and_left_out`).
#[test]
fn cli_a_still_robot_does_not_move_its_landmarks() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let sim = simulate(&LrfSimConfig {
        seed: 2,
        n_scans: 60,
        speed_mps: 0.0,
        ..LrfSimConfig::default()
    });
    let mut m: serde_json::Value = serde_json::from_str(&sim.map_json()).expect("json");
    m["position_sigma_m"] = serde_json::json!(0.001);
    std::fs::write(d.join("map.json"), m.to_string()).expect("map");
    std::fs::write(d.join("scans.csv"), sim.scans_csv()).expect("scans");
    std::fs::write(d.join("truth.csv"), sim.truth_csv()).expect("truth");
    let sweep = sim.config.sweep_s.to_string();
    let out = localize(
        d,
        &["--truth", s(&d.join("truth.csv")), "--sweep-s", &sweep],
    );
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("was it moved"), "{stderr}");
    assert!(stdout.contains("confident wrong poses: 0"), "{stdout}");
}

/// Scan files are one recording: timed files are taken in the order of their times, whatever
/// order they are given in; one file given twice, or files whose times interleave, are
/// refused as scans out of order within a file are, naming the files.
#[test]
fn cli_scan_files_are_taken_in_time_order_and_twice_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 30);
    let text = std::fs::read_to_string(d.join("scans.csv")).expect("scans");
    let mut lines = text.lines();
    let header = lines.next().expect("header");
    let (mut first, mut second) = (vec![header], vec![header]);
    for l in lines {
        let scan: u32 = l
            .split(',')
            .next()
            .and_then(|v| v.parse().ok())
            .expect("scan id");
        if scan < 15 { &mut first } else { &mut second }.push(l);
    }
    let (a, b) = (d.join("a.csv"), d.join("b.csv"));
    std::fs::write(&a, first.join("\n") + "\n").expect("write");
    std::fs::write(&b, second.join("\n") + "\n").expect("write");
    let map = d.join("map.json");
    let poses = d.join("poses.csv");
    let run = |files: &[&Path]| {
        let mut args = vec!["lrf", "localize", "--map", s(&map), "--out", s(&poses)];
        args.extend(files.iter().map(|f| s(f)));
        args.iter().map(|a| a.to_string()).collect::<Vec<String>>()
    };
    // Given the second half first (as a shell lists b.csv before a.csv's later copy, or
    // scan10.csv before scan2.csv), the files are read in time order.
    let args = run(&[&b, &a]);
    let out = odocal(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("30 scans (tracking mode): 30 ok"),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    std::fs::remove_file(&poses).expect("rm");
    let args = run(&[&a, &b, &a]);
    expect_error(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &format!("{} is given twice; give each scan file once", s(&a)),
    );
    // The same file by another name, or a copy: its times repeat the first's.
    let copy = d.join("copy.csv");
    std::fs::copy(&a, &copy).expect("copy");
    let args = run(&[&a, &copy]);
    expect_error(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &format!(
            "{}: its scans from 0 s to 1.4 s overlap those of {}, which run to 1.4 s: the two files hold scans of the same time",
            s(&copy),
            s(&a)
        ),
    );
    assert!(!poses.exists(), "nothing written");
    // In time order, the two halves are the whole recording.
    let args = run(&[&a, &b]);
    let out = odocal(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("30 scans (tracking mode): 30 ok"),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// One file per scan without a t column (scan0.csv, scan1.csv, scan10.csv, … as the shell
/// lists them): the files are taken in number order, as the logger wrote them. Plain order
/// put scan10 after scan1, and the scrambled recording gave 25 confident wrong poses of 27.
#[test]
fn cli_untimed_scan_files_are_taken_in_number_order() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 30);
    let (_, rows) = scan_rows(d);
    let per_scan = d.join("per_scan");
    std::fs::create_dir(&per_scan).expect("mkdir");
    let mut files: Vec<Vec<String>> = Vec::new();
    // The first scan with its times, to mix with the untimed ones.
    let mut timed = vec!["t,angle,range,intensity".to_string()];
    for r in rows {
        let k: usize = r[0].parse().expect("scan id");
        if files.len() <= k {
            files.push(vec!["angle,range,intensity".to_string()]);
        }
        files[k].push(r[2..].join(","));
        if k == 0 {
            timed.push(r[1..].join(","));
        }
    }
    let mut paths: Vec<String> = (0..files.len())
        .map(|k| {
            let path = per_scan.join(format!("scan{k}.csv"));
            std::fs::write(&path, files[k].join("\n") + "\n").expect("write");
            s(&path).to_string()
        })
        .collect();
    // The shell's order.
    paths.sort();
    assert!(paths[2].ends_with("scan10.csv"));
    let (map, truth, poses) = (d.join("map.json"), d.join("truth.csv"), d.join("poses.csv"));
    let mut args = vec!["lrf", "localize", "--map", s(&map), "--out", s(&poses)];
    args.extend(["--truth", s(&truth)]);
    args.extend(paths.iter().map(String::as_str));
    let out = odocal(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("30 scans (tracking mode): 30 ok"),
        "{stdout}"
    );
    assert!(stdout.contains("confident wrong poses: 0;"), "{stdout}");
    // Each file's one scan has the id 0 for want of a `scan` column: the poses number
    // the scans in the order read instead of giving every row scan 0.
    let text = std::fs::read_to_string(&poses).expect("poses");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == "scan")
        .expect("scan column");
    let ids: Vec<String> = lines
        .map(|l| l.split(',').nth(col).unwrap_or("").to_string())
        .collect();
    let expected: Vec<String> = (0..30).map(|k| k.to_string()).collect();
    assert_eq!(ids, expected);
    // Timed and untimed files mixed have no order: the poses' times went backwards.
    let timed_file = per_scan.join("timed0.csv");
    std::fs::write(&timed_file, timed.join("\n") + "\n").expect("write");
    let mixed = d.join("mixed.csv");
    expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            "--out",
            s(&mixed),
            s(&per_scan.join("scan1.csv")),
            s(&timed_file),
        ],
        &format!(
            "{} has scan times (a t column) but {} has none; give all the scan files times, or none",
            s(&timed_file),
            s(&per_scan.join("scan1.csv"))
        ),
    );
    assert!(!mixed.exists());
}

/// Scans of another room against a map with no congruent configuration: every scan is lost
/// or ambiguous, and the layout was blamed ("repeat themselves (a symmetric layout) … add or
/// move a landmark") where `lrf check-map` finds no symmetry. The likely causes are named.
#[test]
fn cli_scans_of_another_map_are_not_blamed_on_its_layout() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    synth_lrf(&a, 1, 50);
    synth_lrf(&b, 3, 50);
    let map = a.join("map.json");
    let check = odocal(&["lrf", "check-map", s(&map)]);
    assert!(
        String::from_utf8_lossy(&check.stdout).contains("verdict: no congruent configuration"),
        "{}",
        String::from_utf8_lossy(&check.stdout)
    );
    let (poses, scans) = (b.join("poses.csv"), b.join("scans.csv"));
    let args = [
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&scans),
        "--out",
        s(&poses),
    ];
    let out = odocal(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("ambiguous, "),
        "some scans are ambiguous: {err}"
    );
    for want in [
        &format!(
            "{} has no congruent configuration (`odocal lrf check-map {}`), so no symmetric layout explains the ambiguous ones: is {} the map of this room",
            s(&map),
            s(&map),
            s(&map)
        ),
        "a scanner mounted upside down mirrors them",
        "--intensity-min 0.5",
        "--max-range-m 5.6 m",
    ] {
        expect_error(&args, want);
    }
    assert!(!err.contains("symmetric layout)"), "{err}");
    assert!(!poses.exists());
}

/// Scan times in milliseconds are refused with the unit named (a truth in seconds matched one
/// scan of 30, and its error passed for the recording's), and a truth that has the time of
/// few of the `ok` scans is called out beside the figures it gives. Epoch seconds (ROS
/// exports; "time 1700000000 s is not a scan time (0 to 3000000 s)" before) give the poses
/// of the same scans timed from 0, against an epoch truth, with every time written in full;
/// nanoseconds are refused as nanoseconds (their spacing names them; epoch nanoseconds are
/// past any time in seconds). Scans at another rate than --rate-hz are refused with theirs
/// named, and scans a whole number of periods apart are read as a recording that keeps one in
/// a few, with the slower rate named.
#[test]
fn cli_scan_times_in_milliseconds_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 30);
    // Rewrites column `col` of every row of `file` with `f` into `name`.
    let rewrite = |file: &str, name: &str, col: usize, f: &dyn Fn(usize, f64) -> f64| {
        let text = std::fs::read_to_string(d.join(file)).expect("read");
        let mut lines = text.lines();
        let mut out = vec![lines.next().expect("header").to_string()];
        for (i, l) in lines.enumerate() {
            let mut r: Vec<String> = l.split(',').map(str::to_string).collect();
            r[col] = format!("{:.6}", f(i, r[col].parse().expect("number")));
            out.push(r.join(","));
        }
        let p = d.join(name);
        std::fs::write(&p, out.join("\n") + "\n").expect("write");
        p
    };
    let ms = rewrite("scans.csv", "ms.csv", 1, &|_, t| t * 1000.0);
    let (map, truth, poses) = (d.join("map.json"), d.join("truth.csv"), d.join("poses.csv"));
    let args = [
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&ms),
        "--out",
        s(&poses),
        "--truth",
        s(&truth),
    ];
    expect_error(
        &args,
        "the scans' median time between scans is 100 s, 1000 times the scanner's period of 0.1 s at --rate-hz 10: are the times in milliseconds?",
    );
    assert!(!poses.exists(), "nothing written");
    // Scans in seconds from a slower scanner than --rate-hz says: the times' float noise
    // printed as 0.10000000000000009.
    let e = expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(&d.join("scans.csv")),
            "--out",
            s(&poses),
            "--rate-hz",
            "1000",
        ],
        "the scans' median time between scans is 0.1 s, 100 times the scanner's period of 0.001 s at --rate-hz 1000: are the times in milliseconds? Give t in seconds (if these are milliseconds, 0.1 ms is 0.0001 s)",
    );
    assert!(!e.contains("0000000"), "{e}");
    // 10 Hz scans at --rate-hz 5: a 133 ms sweep in 100 ms, which gave 48 confident poses up
    // to 116 mm off.
    expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(&d.join("scans.csv")),
            "--out",
            s(&poses),
            "--rate-hz",
            "5",
        ],
        "the scans are 0.1 s apart (median), less than a sweep of 0.133203 s (their 240° at --rate-hz 5), but a scanner does not start a scan before it ends the last: give the scanner's real --rate-hz (these scans come at 10 Hz)",
    );
    assert!(!poses.exists(), "nothing written");
    // 15 Hz scans (the same scans re-timed) at the default --rate-hz 10: just over a sweep
    // apart, de-skewed as if swept in 67 ms instead of 44 they were 3.6 times their bound
    // off (11.1 mm RMS with 300 scans) with no word.
    let q15 = rewrite("scans.csv", "q15.csv", 1, &|_, t| t * 2.0 / 3.0);
    let (q15, poses_s) = (s(&q15), s(&poses));
    expect_error(
        &["lrf", "localize", "--map", s(&map), q15, "--out", poses_s],
        "the scans are 0.066667 s apart (median), 0.67 times the period of 0.1 s at --rate-hz 10 and not a whole number of periods: the scanner runs at another rate, and sweeps in another time than its beams would be given; give the scanner's real --rate-hz 15 (or a whole multiple of it",
    );
    assert!(!poses.exists(), "nothing written");
    let at = |scans: &str, extra: &[&str]| {
        let mut args = vec!["lrf", "localize", "--map", s(&map), scans, "--out", poses_s];
        args.extend_from_slice(extra);
        let out = odocal(&args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{err}");
        std::fs::remove_file(&poses).expect("remove");
        err
    };
    at(q15, &["--rate-hz", "15"]);
    // 5 Hz scans at --rate-hz 10 have the times of every other scan of a 10 Hz scanner (a
    // throttled topic, whose sweep is 67 ms still): accepted, and the slower rate named.
    let q5 = rewrite("scans.csv", "q5.csv", 1, &|_, t| t * 2.0);
    let err = at(s(&q5), &[]);
    assert!(
        err.contains("note: the scans are 2 periods of --rate-hz 10 apart (median), read as one scan kept in 2 of a 10 Hz scanner's; if the scanner itself runs at 5 Hz, give --rate-hz 5"),
        "{err}"
    );
    assert!(!at(s(&q5), &["--rate-hz", "5"]).contains("note:"));
    // A truth whose clock runs 50 ms apart from the scans' after its fifth row.
    let shifted = rewrite("truth.csv", "shifted.csv", 0, &|i, t| {
        if i >= 5 {
            t + 0.05
        } else {
            t
        }
    });
    let out = localize(d, &["--truth", s(&shifted)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains(&format!(
            "warning: {} has the time of only 5 of the 30 ok scans (5 of all 30 scans)",
            s(&shifted)
        )),
        "{err}"
    );
    // The truth of every scan: no such warning.
    let out = localize(d, &["--truth", s(&truth)]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    let from_zero = String::from_utf8_lossy(&out.stdout).into_owned();
    // Stamps to the microsecond, as ROS writes them.
    let epoch = 1_700_000_000.000_123;
    let scans_epoch = rewrite("scans.csv", "epoch.csv", 1, &|_, t| t + epoch);
    let truth_epoch = rewrite("truth.csv", "truth_epoch.csv", 0, &|_, t| t + epoch);
    let traj = d.join("traj.csv");
    let out = localize_judged(&map, &scans_epoch, &poses, &traj, &truth_epoch);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let figures = |o: &str| o.split("vs truth:").nth(1).map(str::to_string);
    assert_eq!(figures(&stdout), figures(&from_zero), "{stdout}");
    assert!(stdout.contains("30 ok"), "{stdout}");
    // Every scan's time and every trajectory row's is the scan's own, to the microsecond.
    for (file, n) in [(&poses, 30), (&traj, 30)] {
        let text = std::fs::read_to_string(file).expect("written");
        let times: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().and_then(|t| t.parse().ok()).expect("t"))
            .collect();
        assert_eq!(times.len(), n, "{text}");
        for (k, t) in times.iter().enumerate() {
            assert!(
                (t - epoch - k as f64 * 0.1).abs() < 1e-6,
                "{}: {t}",
                s(file)
            );
        }
    }
    let ns = rewrite("scans.csv", "ns.csv", 1, &|_, t| t * 1e9);
    expect_error(
        &["lrf", "localize", "--map", s(&map), s(&ns), "--out", s(&poses)],
        "are the times in nanoseconds? Give t in seconds (if these are nanoseconds, 100000000 ns is 0.1 s)",
    );
    let epoch_ns = rewrite("scans.csv", "epoch_ns.csv", 1, &|_, t| (t + epoch) * 1e9);
    let e = expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(&epoch_ns),
            "--out",
            s(&poses),
        ],
        "epoch_ns.csv, line 2, column t: time 1700000000000123",
    );
    assert!(
        e.contains("s is not a scan time (0 to 1e10 s, the year 2286 counted from 1970); give t in seconds, from the recording's start or the epoch (epoch milliseconds / 1000, nanoseconds / 1e9)"),
        "{e}"
    );
}

/// A scan repeated beam for beam under its own time (a driver republishing its last scan)
/// is not localised, and one warning counts it: localised, it gave an `ok` pose 50 mm (45σ)
/// off, with no word.
#[test]
fn cli_a_repeated_scan_is_not_localised() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 3, 30);
    let (header, rows) = scan_rows(d);
    // Scan 12 takes scan 11's beams, keeping its own id and time.
    let eleven: Vec<Vec<String>> = rows.iter().filter(|r| r[0] == "11").cloned().collect();
    let rep = rewrite_scans(&d.join("rep.csv"), &header, &rows, &|scan| {
        let beams = if scan[0][0] == "12" {
            &eleven[..]
        } else {
            scan
        };
        beams
            .iter()
            .map(|b| format!("{},{},{}", scan[0][0], scan[0][1], b[2..].join(",")))
            .collect()
    });
    let (map, poses) = (d.join("map.json"), d.join("poses.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&rep),
        "--out",
        s(&poses),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains(
            "warning: 1 scan repeats the previous scan's ranges and intensities beam for beam"
        ) && err.contains("it was not localised"),
        "{err}"
    );
    let written = std::fs::read_to_string(&poses).expect("poses");
    let row = written
        .lines()
        .find(|l| l.ends_with(",12"))
        .expect("a row for scan 12");
    assert!(
        row.contains(",lost,") && row.contains(",repeated,"),
        "{row}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("29 ok"));
    // Scan 0 republished 30 times: the repeats were warned of and then counted as lost
    // ("29 of 30 scans found no pose: is map.json the map of this room …", 0.2 detections per
    // scan); they are neither lost nor in the detection rate.
    let zero: Vec<Vec<String>> = rows.iter().filter(|r| r[0] == "0").cloned().collect();
    let stuck = rewrite_scans(&d.join("stuck.csv"), &header, &rows, &|scan| {
        zero.iter()
            .map(|b| format!("{},{},{}", scan[0][0], scan[0][1], b[2..].join(",")))
            .collect()
    });
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&stuck),
        "--out",
        s(&poses),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning: 29 scans repeat"), "{err}");
    assert!(
        !err.contains("found no pose") && !err.contains("the map of this room"),
        "{err}"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    // The rate is scan 0's own, the one scan localised.
    let written = std::fs::read_to_string(&poses).expect("poses");
    let n_det: f64 = written
        .lines()
        .nth(1)
        .and_then(|l| l.split(',').nth(6))
        .and_then(|n| n.parse().ok())
        .expect("scan 0's detections");
    let summary = stdout.lines().next().expect("a summary");
    assert!(
        summary.starts_with(
            "lrf localize: 30 scans (tracking mode): 1 ok, 0 ambiguous, 0 lost, 29 repeated; "
        ),
        "{summary}"
    );
    let rate: f64 = summary
        .split("; ")
        .nth(1)
        .and_then(|r| r.strip_suffix(" detections/scan"))
        .and_then(|r| r.parse().ok())
        .expect("a detection rate");
    assert!((rate - n_det).abs() < 0.051, "{summary}: {n_det}");
}

/// Map values no room has: a reflector width in millimetres is refused, and a landmark 50 m
/// from all the others of a 10 m x 8 m room (a mistyped coordinate) is named by its id.
#[test]
fn cli_implausible_map_values_are_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 1);
    let text = std::fs::read_to_string(d.join("map.json")).expect("map");
    let mut map: serde_json::Value = serde_json::from_str(&text).expect("json");
    let mut wide = map.clone();
    wide["reflector_width_m"] = serde_json::json!(80);
    let wide_path = d.join("wide.json");
    std::fs::write(&wide_path, wide.to_string()).expect("write");
    expect_error(
        &["lrf", "check-map", s(&wide_path)],
        "reflector_width_m is 80 m, but a reflector strip is 5 mm to well under 1 m wide: is it in millimetres",
    );
    let far = serde_json::json!({"id": 99, "x_m": 60.0, "y_m": 4.0});
    map["landmarks"]
        .as_array_mut()
        .expect("landmarks")
        .push(far);
    let far_path = d.join("far.json");
    std::fs::write(&far_path, map.to_string()).expect("write");
    let out = odocal(&["lrf", "check-map", s(&far_path)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("landmark id 99 at (60.000, 4.000) m is ")
            && err.contains("so no scan sees it with another"),
        "{err}"
    );
    // The map as written: no warning.
    let out = odocal(&["lrf", "check-map", s(&d.join("map.json"))]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
}

/// A truth whose theta is in degrees: every confident pose was refused as wrong, with the map
/// and the scans blamed, though the positions agreed to 2 mm; and `report` showed "heading
/// RMS 104.6 deg" as the poses' accuracy. Both name the truth's heading.
#[test]
fn cli_a_truth_with_headings_in_degrees_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 30);
    let truth = std::fs::read_to_string(d.join("truth.csv")).expect("truth");
    let mut lines = truth.lines();
    let header = lines.next().expect("header");
    let col = header
        .split(',')
        .position(|h| h == "theta")
        .expect("theta column");
    let mut degrees = vec![header.to_string()];
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
        f[col] = format!("{}", f[col].parse::<f64>().expect("theta").to_degrees());
        degrees.push(f.join(","));
    }
    let deg = d.join("truth_deg.csv");
    std::fs::write(&deg, degrees.join("\n") + "\n").expect("write");
    let (map, scans, poses) = (d.join("map.json"), d.join("scans.csv"), d.join("poses.csv"));
    let args = [
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&scans),
        "--out",
        s(&poses),
        "--truth",
        s(&deg),
    ];
    expect_error(&args, "wrong against");
    expect_error(&args, "in heading only (position RMS");
    expect_error(&args, "is its theta in radians (not degrees)");
    // The poses localised without a truth, then judged against the degrees by a report: it
    // used to draw them with a warning in the page and exit 0; refused now as above.
    assert!(localize(d, &[]).status.success());
    let html = d.join("r.html");
    let report = [
        "report",
        "--out",
        s(&html),
        "--lrf-poses",
        s(&poses),
        "--lrf-truth",
        s(&deg),
        "--lrf-map",
        s(&map),
    ];
    expect_error(&report, "in heading only (position RMS");
    expect_error(&report, "is its theta in radians (not degrees)");
    assert!(!html.exists());
    // Another recording's truth (same times, another path: here the path moved 1 m) was
    // drawn as "position RMS 9.7 m against the truth"; refused as `lrf localize --truth`
    // refuses it.
    let col = |name: &str| header.split(',').position(|h| h == name).expect("a column");
    let (xcol, ycol) = (col("x"), col("y"));
    let other = d.join("other");
    std::fs::create_dir_all(&other).expect("mkdir");
    // The truth with `change(column, value)` made to every row's x and y, as `name`.
    let rewritten = |name: &str, change: &dyn Fn(usize, f64) -> f64| {
        let rows: Vec<String> = truth
            .lines()
            .enumerate()
            .map(|(i, l)| {
                let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
                for c in [xcol, ycol].into_iter().filter(|_| i > 0) {
                    f[c] = format!("{}", change(c, f[c].parse::<f64>().expect("x, y")));
                }
                f.join(",")
            })
            .collect();
        let path = other.join(name);
        std::fs::write(&path, rows.join("\n") + "\n").expect("write");
        path
    };
    let html2 = d.join("r2.html");
    let report_against = |truth: &Path, want: &str| {
        expect_error(
            &[
                "report",
                "--out",
                s(&html2),
                "--lrf-poses",
                s(&poses),
                "--lrf-truth",
                s(truth),
            ],
            want,
        );
        assert!(!html2.exists());
    };
    let moved = rewritten("truth.csv", &|c, v| if c == xcol { v + 1.0 } else { v });
    report_against(
        &moved,
        "confident laser poses it has a time for are wrong against it",
    );
    // The truth in millimetres: its unit is named, by `lrf localize --truth` and `report`.
    let truth_mm = rewritten("truth_mm.csv", &|_, v| v * 1e3);
    let unit = "is the truth in millimetres or centimetres? it must be in metres";
    report_against(&truth_mm, unit);
    let mut localize_mm = args.to_vec();
    let last = localize_mm.len() - 1;
    localize_mm[last] = s(&truth_mm);
    expect_error(&localize_mm, unit);
    // A map in another frame (here moved 100 m) drew the poses among landmarks they never
    // saw, exit 0; refused now.
    let mut shifted: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).expect("map")).expect("json");
    for l in shifted["landmarks"].as_array_mut().expect("landmarks") {
        l["x_m"] = serde_json::json!(l["x_m"].as_f64().expect("x_m") + 100.0);
    }
    let shifted_path = other.join("map.json");
    std::fs::write(&shifted_path, shifted.to_string()).expect("write");
    let mut with_map = vec!["report", "--out", s(&html2), "--lrf-poses", s(&poses)];
    with_map.extend(["--lrf-map", s(&shifted_path)]);
    expect_error(
        &with_map,
        "confident laser poses matched more landmarks than it has facing them within the scanner's range (5.6 m) and field of view (240°)",
    );
    assert!(!html2.exists());
    with_map[6] = s(&map);
    assert!(odocal(&with_map).status.success());
}

/// `synth lrf --symmetric` placed half the landmarks asked for (30 gave 16, 8 gave 4), unsaid;
/// it places them all, refuses an odd count (pairs), and a room too crowded is named.
#[test]
fn cli_a_symmetric_layout_has_the_landmarks_asked_for() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    for n in [8usize, 30] {
        let out = d.join(format!("s{n}"));
        let res = odocal(&[
            "synth",
            "lrf",
            "--out",
            s(&out),
            "--symmetric",
            "--landmarks",
            &n.to_string(),
            "--scans",
            "2",
        ]);
        assert!(res.status.success());
        let map: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("map.json")).expect("map"))
                .expect("json");
        assert_eq!(map["landmarks"].as_array().map(Vec::len), Some(n));
    }
    expect_error(
        &[
            "synth",
            "lrf",
            "--out",
            s(&d.join("odd")),
            "--symmetric",
            "--landmarks",
            "31",
        ],
        "places landmarks in pairs; give an even number",
    );
}

/// A bright strip saturates some receivers into beams without a return, in the middle of the
/// strip as well as at its ends. One such beam split a reflector into two detections (7.3
/// detections per scan became 11.2), and the poses were 9.3 mm RMS from the truth with σ of
/// 3.1 mm and no word. Up to two are now bridged, and a beam without a return beside a strip
/// is no evidence of where it ends: the poses stay as close to the truth as without the
/// dropouts, and their σ honest.
#[test]
fn cli_beams_without_a_return_inside_a_reflector_keep_it_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 4, 40);
    let (header, rows) = scan_rows(d);
    let (map, truth) = (d.join("map.json"), d.join("truth.csv"));
    let run = |scans: &Path| {
        let (poses, traj) = (d.join("p.csv"), d.join("t.csv"));
        let out = localize_judged(&map, scans, &poses, &traj, &truth);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let per_scan: f64 = text
            .split(" detections/scan")
            .next()
            .and_then(|l| l.rsplit(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no detections/scan in {text}"));
        let (ok, rms) = ok_and_rms(&out);
        let (z_xy, z_theta, ..) = error_over_sigma(&traj, &truth);
        (per_scan, ok, rms, z_xy, z_theta)
    };
    let clean = run(&d.join("scans.csv"));
    // Every 7th beam, or two in every five, loses its return (range 0, or inf as ROS writes
    // it), reflector or not; the strips' fewer hits leave the poses less sure, as their σ says.
    for (name, drop, value, worse) in [
        (
            "one.csv",
            &(|i: usize| i.is_multiple_of(7)) as &dyn Fn(usize) -> bool,
            "0",
            1.6,
        ),
        ("inf.csv", &|i: usize| i.is_multiple_of(7), "inf", 1.6),
        ("two.csv", &|i: usize| i % 5 < 2, "0", 2.5),
    ] {
        let lines: Vec<String> = std::iter::once(header.clone())
            .chain(rows.iter().enumerate().map(|(i, r)| {
                let mut r = r.clone();
                if drop(i) {
                    (r[3], r[4]) = (value.to_string(), "0".to_string());
                }
                r.join(",")
            }))
            .collect();
        let scans = d.join(name);
        std::fs::write(&scans, lines.join("\n") + "\n").expect("write");
        let (per_scan, ok, rms, z_xy, z_theta) = run(&scans);
        println!(
            "{name}: {per_scan} detections/scan ({} without dropouts), {ok} ok, position RMS {rms:.1} mm ({:.1}), error/σ {z_xy:.2} (x,y) {z_theta:.2} (θ)",
            clean.0, clean.2
        );
        assert!(
            per_scan <= clean.0 + 0.2,
            "{name}: {per_scan} against {}",
            clean.0
        );
        assert!(
            ok + 2 >= clean.1 && rms <= worse * clean.2,
            "{name}: {ok} ok, {rms} mm"
        );
        assert!(z_xy < 1.5 && z_theta < 1.5, "{name}: {z_xy} {z_theta}");
    }
}

/// A range noise given 100 times too small (`--sigma-range-m 0.0001` for a 10 mm scanner)
/// put the poses 5.9 times their Cramér–Rao bound from the truth with exit 0, and the only
/// warning blamed the map: the σ options are named now.
#[test]
fn cli_poses_far_beyond_their_bound_name_the_noise_given() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 3, 40);
    let truth = d.join("truth.csv");
    let honest = localize(d, &["--truth", s(&truth)]);
    assert!(honest.status.success());
    assert!(!String::from_utf8_lossy(&honest.stderr).contains("too small"));
    let out = localize(d, &["--truth", s(&truth), "--sigma-range-m", "0.0001"]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("times (heading) their Cramér–Rao bound from the truth, so their σ are too small for these scans: is --sigma-range-m 0.0001 the scanner's range noise"),
        "{err}"
    );
    // A σ so small that no scan finds a pose: named with the σ under which they do, where it
    // used to blame the map.
    let tight = d.join("tight");
    synth_lrf(&tight, 2, 10);
    let out = localize(&tight, &["--sigma-range-m", "0.001"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("with --sigma-range-m 0.01 m (10 times the 0.001 m given) 10 of the first 10 scans find a pose, where 0 did: matches are gated at a few σ of --sigma-range-m")
            && !err.contains("map of this room"),
        "{err}"
    );
    assert!(!tight.join("poses.csv").exists());
    // A σ far too large lets every scan fit the map in several places: named too, where the
    // map was blamed.
    let loose = d.join("loose");
    synth_lrf(&loose, 1, 20);
    let out = localize(&loose, &["--sigma-range-m", "0.2"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("with --sigma-range-m 0.02 m (1/10 of the 0.2 m given) 20 of the first 20 scans find a pose, where 0 did: matches are gated at a few σ of --sigma-range-m, so a σ far above")
            && !err.contains("map of this room"),
        "{err}"
    );
    // Another room's map is still named as such: no σ finds its poses.
    std::fs::copy(d.join("map.json"), tight.join("map.json")).expect("copy");
    let out = localize(&tight, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("map of this room") && !err.contains("--sigma-range-m"),
        "{err}"
    );
}

/// `synth lrf`'s scans in `d` rewritten into `out`, each data row's (angle, range, intensity)
/// passed through `f`.
fn beams_rewritten(d: &Path, out: &Path, f: impl Fn(f64, f64, f64) -> (f64, f64)) {
    let text = std::fs::read_to_string(d.join("scans.csv")).expect("scans");
    let mut lines = text.lines();
    let header = lines.next().expect("header");
    assert_eq!(header, "scan,t,angle,range,intensity");
    let mut w = format!("{header}\n");
    for l in lines {
        let v: Vec<&str> = l.split(',').collect();
        let num = |i: usize| v[i].parse::<f64>().expect("number");
        let (a, r) = f(num(2), num(3), num(4));
        w += &format!("{},{},{a},{r},{}\n", v[0], v[1], v[4]);
    }
    std::fs::write(out, w).expect("write scans");
}

/// A scanner whose ranges read 2 cm long, or whose angle step is 0.5 % off the one logged,
/// leaves every landmark's residuals off alike: 12 and 11 landmarks were named as moved and
/// 68 and 113 `ok` poses lay beyond 5σ. The range offset and angle scale are fitted over the
/// recording, named with their values, taken out of the scans, and the poses are as good as
/// the unbiased scans' (no pose beyond 4σ), with no landmark blamed.
#[test]
fn cli_a_range_offset_or_angle_scale_is_named_and_corrected() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 3, 300, &[]);
    let (map, poses, traj, truth) = (
        d.join("map.json"),
        d.join("poses.csv"),
        d.join("traj.csv"),
        d.join("truth.csv"),
    );
    let long = d.join("long.csv");
    beams_rewritten(d, &long, |a, r, _| (a, if r > 0.0 { r + 0.02 } else { r }));
    let short = d.join("short.csv");
    // Only the reflectors' returns read short (a range walk with intensity).
    beams_rewritten(d, &short, |a, r, i| {
        (a, if r > 0.0 && i >= 0.5 { r - 0.04 } else { r })
    });
    let scaled = d.join("scaled.csv");
    beams_rewritten(d, &scaled, |a, r, _| (a * 0.995, r));
    for (scans, said) in [
        (&long, "the ranges read 20.1 ± 0.2 mm long"),
        (&short, "the ranges read 39.8 ± 0.2 mm short"),
        (
            &scaled,
            "the angles read 0.99535 ± 0.00008 times the true ones",
        ),
    ] {
        let out = localize_judged(&map, scans, &poses, &traj, &truth);
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert!(stderr.contains(said), "{stderr}");
        assert!(
            stderr.contains("every range and angle was corrected by that"),
            "{stderr}"
        );
        assert!(!stderr.contains("warning: landmark"), "{stderr}");
        assert!(stdout.contains("299 ok, 0 ambiguous, 1 lost"), "{stdout}");
        assert!(stdout.contains("confident wrong poses: 0;"), "{stdout}");
        let (z, h, worst, at) = error_over_sigma(&traj, &truth);
        assert!(z <= 1.2 && h <= 1.2, "error/σ RMS {z:.2}, heading {h:.2}");
        assert!(worst <= 4.0, "the pose at t = {at} s is {worst:.1}σ off");
    }
    // The scans as recorded are left as they are.
    let out = localize_judged(&map, &d.join("scans.csv"), &poses, &traj, &truth);
    assert!(
        !String::from_utf8_lossy(&out.stderr).contains("warning:"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// In an exact map (position_sigma_m 0) reflectors re-stuck 5 cm along their walls are seen
/// mostly at a slant, where a strip's centre is known along it only within centimetres, and
/// each pulled the poses matching it: two moved left 20 poses beyond 5σ (37 mm off with a σ of
/// 3 mm) and one surveyed 2 cm off left 5 (13 mm, 12.9σ), none named. A landmark is now judged
/// by its residuals at the pose the other landmarks give, which its pull does not shrink.
#[test]
fn cli_a_landmark_off_its_place_in_an_exact_map_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 3, 300, &[]);
    let (scans, poses, traj, truth) = (
        d.join("scans.csv"),
        d.join("poses.csv"),
        d.join("traj.csv"),
        d.join("truth.csv"),
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    assert_eq!(m["position_sigma_m"], serde_json::json!(0.0));
    let shifted = |moves: &dyn Fn(u64, f64, f64, f64) -> (f64, f64), name: &str| {
        let mut m = m.clone();
        for l in m["landmarks"].as_array_mut().expect("landmarks") {
            let id = l["id"].as_u64().expect("id");
            let f = l["facing_rad"].as_f64().expect("facing");
            let (x, y) = (l["x_m"].as_f64().expect("x"), l["y_m"].as_f64().expect("y"));
            let (nx, ny) = moves(id, f, x, y);
            l["x_m"] = serde_json::json!(nx);
            l["y_m"] = serde_json::json!(ny);
            let v = &mut l["visibility_line"];
            if v.get("a").is_some() {
                let a = v["a"].as_f64().expect("a");
                v["b"] = serde_json::json!(ny - a * nx);
            } else {
                v["x_m"] = serde_json::json!(nx);
            }
        }
        let p = d.join(name);
        std::fs::write(&p, m.to_string()).expect("write");
        p
    };
    let along = shifted(
        &|id, f, x, y| {
            if [8, 18].contains(&id) {
                (x - 0.05 * f.sin(), y + 0.05 * f.cos())
            } else {
                (x, y)
            }
        },
        "along.json",
    );
    let surveyed = shifted(
        &|id, _, x, y| if id == 4 { (x, y + 0.02) } else { (x, y) },
        "surveyed.json",
    );
    // Moved 5 cm, a landmark is left out of every fit as beyond its noise, and was named
    // nowhere.
    let farther = shifted(
        &|id, _, x, y| if id == 18 { (x, y + 0.05) } else { (x, y) },
        "farther.json",
    );
    for (map, said) in [
        (&along, "warning: landmark 18 of {} sits "),
        (&along, "warning: landmark 8 of {} was detected 48 mm from its mapped position"),
        (&surveyed, "warning: landmark 4 of {} sits 23 mm from its mapped position"),
        (
            &farther,
            "warning: landmark 18 of {} was detected 51 mm from its mapped position along (0.05, -1.00) in 67 scans",
        ),
    ] {
        let out = localize_judged(map, &scans, &poses, &traj, &truth);
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert!(stderr.contains(&said.replace("{}", s(map))), "{stderr}");
        assert!(stdout.contains("confident wrong poses: 0;"), "{stdout}");
        let (z, h, worst, at) = error_over_sigma(&traj, &truth);
        assert!(z <= 1.2 && h <= 1.2, "error/σ RMS {z:.2}, heading {h:.2}");
        assert!(worst <= 4.0, "the pose at t = {at} s is {worst:.1}σ off");
    }
}

/// Scans without a `t` column whose ids skip (scans dropped by the logger) were timed by
/// their order, so the motion across a gap was taken as one period's and the sweeps after it
/// de-skewed wrongly: 38 of 173 `ok` poses lay beyond 5σ, with no word. They are timed by their
/// ids now, and the gap is said.
#[test]
fn cli_untimed_scans_whose_ids_skip_are_timed_by_their_ids() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf_with(d, 3, 150, &[]);
    let (_, rows) = scan_rows(d);
    let kept = |id: u64| (id * 7919) % 10 >= 4;
    let scans = rewrite_scans(
        &d.join("dropped.csv"),
        "scan,angle,range,intensity",
        &rows,
        &|scan| {
            let id: u64 = scan[0][0].parse().expect("scan id");
            if !kept(id) {
                return Vec::new();
            }
            scan.iter()
                .map(|r| format!("{},{},{},{}", r[0], r[2], r[3], r[4]))
                .collect()
        },
    );
    // The truth at each kept scan's time counted from the first kept id.
    let truth_text = std::fs::read_to_string(d.join("truth.csv")).expect("truth");
    let mut lines = truth_text.lines();
    let mut truth = format!("{}\n", lines.next().expect("header"));
    let first = (0..).find(|&id| kept(id)).expect("a kept scan");
    for (id, l) in lines.enumerate() {
        let id = id as u64;
        if kept(id) {
            let rest = l.split_once(',').expect("a time").1;
            truth += &format!("{:.3},{rest}\n", (id - first) as f64 * 0.1);
        }
    }
    let truth_path = d.join("truth_by_id.csv");
    std::fs::write(&truth_path, truth).expect("write truth");
    let (poses, traj) = (d.join("poses.csv"), d.join("traj.csv"));
    let out = localize_judged(&d.join("map.json"), &scans, &poses, &traj, &truth_path);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("note: the scans have no t column and 56 of the scan ids from 1 to 146 are missing: each scan is timed by its id"),
        "{stderr}"
    );
    let (z, h, worst, at) = error_over_sigma(&traj, &truth_path);
    assert!(z <= 1.2 && h <= 1.2, "error/σ RMS {z:.2}, heading {h:.2}");
    assert!(worst <= 5.5, "the pose at t = {at} s is {worst:.1}σ off");
}

/// `--max-range-m 0.5` (a range shorter than the landmarks' spacing) named 10 landmarks one by
/// one as mistyped coordinates before the real cause: the range given is named once.
#[test]
fn cli_a_max_range_shorter_than_the_landmarks_spacing_is_named_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 10);
    let out = localize(d, &["--max-range-m", "0.5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(
            "of its 30 landmarks are more than twice --max-range-m 0.5 m from every other"
        ) && err.contains("is --max-range-m the scanner's range (its data sheet's), in metres?")
            && !err.contains("is a coordinate mistyped"),
        "{err}"
    );
}

/// An export that writes only the beams with a return leaves a scan's angles skipping whole
/// steps: refused as a "mismatched angle step", where the missing beams are beams without a
/// return. They are put back so, and the poses are those of the scans in full.
#[test]
fn cli_scans_without_their_no_return_rows_give_the_same_poses() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 30);
    let (header, rows) = scan_rows(d);
    let returns = rewrite_scans(&d.join("returns.csv"), &header, &rows, &|scan| {
        scan.iter()
            .filter(|r| r[3].parse::<f64>().expect("range") > 0.0)
            .map(|r| r.join(","))
            .collect()
    });
    assert!(
        std::fs::read_to_string(&returns)
            .expect("read")
            .lines()
            .count()
            < rows.len(),
        "some beams had no return"
    );
    let truth = d.join("truth.csv");
    let full = localize(d, &["--truth", s(&truth)]);
    let (map, poses) = (d.join("map.json"), d.join("poses_returns.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&returns),
        "--out",
        s(&poses),
        "--truth",
        s(&truth),
    ]);
    let (a, b) = (
        String::from_utf8_lossy(&full.stdout),
        String::from_utf8_lossy(&out.stdout),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(a.lines().nth(1), b.lines().nth(1), "{a}\n{b}");
}

/// Reflectors whose returns dim with range fall below `--intensity-min` far off, and the far
/// ones were asked "is it still there? put it back, or remove it". A missed landmark whose
/// place returns brighter than the wall beside it names the threshold instead.
#[test]
fn cli_reflectors_too_dim_for_the_threshold_name_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 100);
    let (header, rows) = scan_rows(d);
    let dim = rewrite_scans(&d.join("dim.csv"), &header, &rows, &|scan| {
        scan.iter()
            .map(|r| {
                let range: f64 = r[3].parse().expect("range");
                let i: f64 = r[4].parse().expect("intensity");
                let i = i * (2.2 / range.max(0.01)).min(1.0);
                format!("{},{},{},{},{i:.3}", r[0], r[1], r[2], r[3])
            })
            .collect()
    });
    let (map, poses) = (d.join("map.json"), d.join("poses.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&dim),
        "--out",
        s(&poses),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: landmark 24 of")
            && err.contains("in view in 14 scans and not seen in 14 of them, but in 14 of those a return lay at its place, at intensity 0.428 (median), below --intensity-min 0.5"),
        "{err}"
    );
    assert!(!err.contains("is it still there?"), "{err}");
}

/// A map of landmarks alone (id, x, y: no walls, no facing) mirrored to the room, its y axis
/// flipped or its x and y swapped, fitted 232 of 300 scans by coincidence of a few landmarks,
/// 12.1 m RMS off the truth and 222 of them outside the landmarks, with exit 0. Such a map is
/// refused, naming the mirror; the same export not mirrored gives its poses within
/// centimetres of the truth.
#[test]
fn cli_a_map_mirrored_to_the_room_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 3, 120);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    let export = |name: &str, f: &dyn Fn(f64, f64) -> (f64, f64)| {
        let landmarks: Vec<serde_json::Value> = m["landmarks"]
            .as_array()
            .expect("landmarks")
            .iter()
            .map(|l| {
                let (x, y) = f(
                    l["x_m"].as_f64().expect("x_m"),
                    l["y_m"].as_f64().expect("y_m"),
                );
                serde_json::json!({"id": l["id"], "x_m": x, "y_m": y})
            })
            .collect();
        let path = d.join(name);
        let map = serde_json::json!({"format": m["format"], "landmarks": landmarks});
        std::fs::write(&path, map.to_string()).expect("write map");
        path
    };
    let scans = d.join("scans.csv");
    let poses = d.join("poses.csv");
    for (name, f) in [
        (
            "mirrored.json",
            &(|x, y: f64| (x, -y)) as &dyn Fn(f64, f64) -> (f64, f64),
        ),
        ("swapped.json", &|x, y| (y, x)),
    ] {
        let map = export(name, f);
        let e = expect_error(
            &[
                "lrf",
                "localize",
                "--map",
                s(&map),
                s(&scans),
                "--out",
                s(&poses),
            ],
            "ok poses lie outside the landmarks of",
        );
        assert!(
            e.contains(
                "the scans and the map are mirror images of each other, so nothing was written"
            ),
            "{e}"
        );
        assert!(
            e.contains("the map is a mirror image of the room (its y axis flipped, a left-handed frame, or x and y swapped, northing before easting)"),
            "{e}"
        );
        assert!(!poses.exists(), "{name}: nothing written");
    }
    let plain = export("plain.json", &|x, y| (x, y));
    let out = localize_judged(
        &plain,
        &scans,
        &poses,
        &d.join("traj.csv"),
        &d.join("truth.csv"),
    );
    let (ok, rms_mm) = ok_and_rms(&out);
    assert!(ok >= 100, "{ok} ok of 120");
    assert!(rms_mm < 10.0, "position RMS {rms_mm} mm");
}

/// One untimed scan per file (`scanN.csv`, as a logger writes them) with scan10–scan14
/// missing: the scans after the gap were timed by their order, 0.5 s early (every later pose
/// 230 mm off at its time), and a warning blamed a glint. They are timed by the numbers in
/// the files' names, the missing ones named.
#[test]
fn cli_untimed_scan_files_with_numbers_missing_are_timed_by_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 2, 60);
    let (_, rows) = scan_rows(d);
    let per_scan = d.join("per_scan");
    std::fs::create_dir(&per_scan).expect("mkdir");
    let mut files: Vec<Vec<String>> = Vec::new();
    for r in rows {
        let k: usize = r[0].parse().expect("scan id");
        if files.len() <= k {
            files.push(vec!["angle,range,intensity".to_string()]);
        }
        files[k].push(r[2..].join(","));
    }
    let mut args: Vec<String> = Vec::new();
    for (k, f) in files.iter().enumerate() {
        if (10..=14).contains(&k) {
            continue;
        }
        let path = per_scan.join(format!("scan{k}.csv"));
        std::fs::write(&path, f.join("\n") + "\n").expect("write");
        args.push(s(&path).to_string());
    }
    let (map, truth, poses) = (d.join("map.json"), d.join("truth.csv"), d.join("poses.csv"));
    let traj = d.join("traj.csv");
    let mut all = vec!["lrf", "localize", "--map", s(&map), "--out", s(&poses)];
    all.extend(["--truth", s(&truth), "--trajectory", s(&traj)]);
    all.extend(args.iter().map(String::as_str));
    let out = odocal(&all);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(
        stderr.contains("note: the scan files have no t column and 5 of the numbers in their names from 0 to 59 are missing (10–14): each scan is timed by its file's number"),
        "{stderr}"
    );
    let (ok, rms_mm) = ok_and_rms(&out);
    assert!(ok >= 50, "{ok} ok of 55");
    assert!(rms_mm < 10.0, "position RMS {rms_mm} mm");
    let (z, h, worst, at) = error_over_sigma(&traj, &truth);
    assert!(z <= 1.5 && h <= 1.5, "error/σ RMS {z:.2}, heading {h:.2}");
    assert!(worst <= 5.5, "the pose at t = {at} s is {worst:.1}σ off");
}

/// A time column named other than `t` was passed over: with `timestamp`, the ids counting
/// on over a second of dropped scans, 139 of 188 ok poses were timed 1 s late (435 mm RMS
/// at their times) with exit 0; `stamp` without a scan column read every row as one scan.
/// Both are read as the time in seconds; a time in another unit is refused by its column.
#[test]
fn cli_a_time_column_under_another_name_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 100);
    let (_, rows) = scan_rows(d);
    // Scans 30–39 dropped, the export's counter consecutive over the gap.
    let timestamp = rewrite_scans(
        &d.join("timestamp.csv"),
        "scan,timestamp,angle,range,intensity",
        &rows,
        &|scan| {
            let id: u64 = scan[0][0].parse().expect("scan id");
            if (30..40).contains(&id) {
                return Vec::new();
            }
            let renumbered = if id >= 40 { id - 10 } else { id };
            scan.iter()
                .map(|r| format!("{renumbered},{}", r[1..].join(",")))
                .collect()
        },
    );
    let stamp = rewrite_scans(
        &d.join("stamp.csv"),
        "stamp,angle,range,intensity",
        &rows,
        &|scan| scan.iter().map(|r| r[1..].join(",")).collect(),
    );
    let truth = d.join("truth.csv");
    let (poses, traj) = (d.join("poses.csv"), d.join("traj.csv"));
    for scans in [&timestamp, &stamp] {
        let out = localize_judged(&d.join("map.json"), scans, &poses, &traj, &truth);
        let (ok, rms_mm) = ok_and_rms(&out);
        assert!(ok >= 85, "{}: {ok} ok", s(scans));
        assert!(rms_mm < 10.0, "{}: position RMS {rms_mm} mm", s(scans));
        let (z, h, worst, at) = error_over_sigma(&traj, &truth);
        assert!(z <= 1.5 && h <= 1.5, "error/σ RMS {z:.2}, heading {h:.2}");
        assert!(worst <= 5.5, "the pose at t = {at} s is {worst:.1}σ off");
    }
    let ms = rewrite_scans(
        &d.join("ms.csv"),
        "scan,time_ms,angle,range,intensity",
        &rows,
        &|scan| scan.iter().map(|r| r.join(",")).collect(),
    );
    let map = d.join("map.json");
    expect_error(
        &["lrf", "localize", "--map", s(&map), s(&ms), "--out", s(&poses)],
        "column time_ms: column \"time_ms\" looks like the scans' times, but odocal reads them in seconds from a column named t",
    );
}

/// A robot driven out of the mapped area (the map cut to its landmarks east of x = 5 m) gave
/// one `ok` pose 4.7 m and 180° off (100σ) among lost and ambiguous scans, with no word, as
/// lone poses were left out only when most scans were lost (here 45 %). Every `ok` pose left
/// is within centimetres of the truth, and the lone one is named.
#[test]
fn cli_a_lone_pose_outside_the_mapped_area_is_left_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 4, 300);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    let east: Vec<serde_json::Value> = m["landmarks"]
        .as_array()
        .expect("landmarks")
        .iter()
        .filter(|l| l["x_m"].as_f64().is_some_and(|x| x > 5.0))
        .cloned()
        .collect();
    m["landmarks"] = serde_json::Value::Array(east);
    let map = d.join("east.json");
    std::fs::write(&map, m.to_string()).expect("write map");
    let (poses, traj, truth) = (d.join("poses.csv"), d.join("traj.csv"), d.join("truth.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&d.join("scans.csv")),
        "--out",
        s(&poses),
        "--trajectory",
        s(&traj),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("among scans without one: a lone pose among lost scans (a robot driven out of the mapped area"),
        "{stderr}"
    );
    let (_, _, worst, at) = error_over_sigma(&traj, &truth);
    assert!(worst <= 6.0, "the pose at t = {at} s is {worst:.1}σ off");
}

/// Scans wider than the default field of view are refused naming `--fov-deg 240` as typed,
/// where the message said `--fov-deg 239.99999999999997`.
#[test]
fn cli_the_default_field_of_view_is_named_as_typed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 3);
    let (header, rows) = scan_rows(d);
    // Every angle 1.2 times: the beams span 288°, evenly.
    let wide = rewrite_scans(&d.join("wide.csv"), &header, &rows, &|scan| {
        scan.iter()
            .map(|r| {
                let mut r = r.clone();
                r[2] = format!("{}", 1.2 * r[2].parse::<f64>().expect("angle"));
                r.join(",")
            })
            .collect()
    });
    let (map, poses) = (d.join("map.json"), d.join("poses.csv"));
    let e = expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(&wide),
            "--out",
            s(&poses),
        ],
        "--fov-deg 240: the scans' beams span 287.7°",
    );
    assert!(!e.contains("239.9"), "{e}");
}

/// A scanner 4 cm noisy in range (1σ) at the default --sigma-range-m 0.01: the χ² warning
/// said "check the landmarks named above" with none named. It now names the range noise the
/// residuals imply, between the σ given and the scans' true 41 mm (gating trims the
/// largest), and the option to give.
#[test]
fn cli_scans_noisier_than_the_sigma_given_name_the_noise() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 100);
    let (header, rows) = scan_rows(d);
    // A fixed sequence of normal deviates (sum of 12 uniforms), so the test is the same
    // every run.
    let state = std::cell::Cell::new(12345u64);
    let gauss = || {
        let mut sum = 0.0;
        for _ in 0..12 {
            let x = state
                .get()
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state.set(x);
            sum += (x >> 11) as f64 / (1u64 << 53) as f64;
        }
        sum - 6.0
    };
    let noisy = rewrite_scans(&d.join("noisy.csv"), &header, &rows, &|scan| {
        scan.iter()
            .map(|r| {
                let mut r = r.clone();
                let range: f64 = r[3].parse().expect("range");
                if range > 0.0 {
                    r[3] = format!("{:.4}", (range + 0.04 * gauss()).max(0.03));
                }
                r.join(",")
            })
            .collect()
    });
    let (map, poses) = (d.join("map.json"), d.join("poses.csv"));
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&noisy),
        "--out",
        s(&poses),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        !stderr.contains("check the landmarks named above"),
        "{stderr}"
    );
    let mm: f64 = stderr
        .split("the residuals imply a range noise of about ")
        .nth(1)
        .and_then(|t| t.split(" mm").next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no implied noise in {stderr}"));
    assert!((15.0..=41.0).contains(&mm), "implied {mm} mm");
    assert!(stderr.contains("give --sigma-range-m 0.0"), "{stderr}");
}

/// A map of landmarks alone (no facings, no walls) takes every reflector for visible from
/// all sides: the reflectors the scanner saw only from behind (every one of them there, in
/// the synthetic room) were called gone, "remove it from the map". The warning now asks for
/// their facing_rad.
#[test]
fn cli_a_landmark_unseen_in_a_map_without_facings_asks_for_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 3, 300);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    let landmarks: Vec<serde_json::Value> = m["landmarks"]
        .as_array()
        .expect("landmarks")
        .iter()
        .map(|l| serde_json::json!({"id": l["id"], "x_m": l["x_m"], "y_m": l["y_m"]}))
        .collect();
    let m = serde_json::json!({"format": m["format"], "landmarks": landmarks});
    let map = d.join("no_facing.json");
    std::fs::write(&map, m.to_string()).expect("write map");
    let poses = d.join("poses.csv");
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&d.join("scans.csv")),
        "--out",
        s(&poses),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let unseen: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("is it still there?"))
        .collect();
    assert!(!unseen.is_empty(), "{stderr}");
    for l in unseen {
        assert!(
            l.ends_with("give its facing_rad (the direction it faces, radians) so that it is expected only where it can be seen"),
            "{l}"
        );
    }
}

/// A scan file whose last line was cut short (a logger stopped while writing it) was refused
/// whole as a "malformed CSV row". The partial row is left out with a warning, and every
/// scan gives its pose as with the file whole; a malformed row inside the file is still
/// refused.
#[test]
fn cli_a_scan_file_cut_short_in_its_last_line_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 20);
    let text = std::fs::read_to_string(d.join("scans.csv")).expect("scans");
    let last = text.trim_end().rfind('\n').expect("rows") + 1;
    let cut = d.join("cut.csv");
    // The last row's first two fields and part of the third.
    let end = last + text[last..].match_indices(',').nth(1).expect("fields").0 + 3;
    std::fs::write(&cut, &text[..end]).expect("write");
    let (map, truth) = (d.join("map.json"), d.join("truth.csv"));
    let poses = d.join("poses.csv");
    let out = odocal(&[
        "lrf",
        "localize",
        "--map",
        s(&map),
        s(&cut),
        "--out",
        s(&poses),
        "--truth",
        s(&truth),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "is cut short with no line end (a logger stopped while writing it) and was left out"
        ),
        "{stderr}"
    );
    let (ok, rms_mm) = ok_and_rms(&out);
    assert!(ok >= 19, "{ok} ok of 20");
    assert!(rms_mm < 10.0, "position RMS {rms_mm} mm");
    // The same row cut short inside the file is no logger's stop.
    let inside = d.join("inside.csv");
    std::fs::write(&inside, format!("{}\n{}", &text[..end], &text[last..])).expect("write");
    expect_error(
        &[
            "lrf",
            "localize",
            "--map",
            s(&map),
            s(&inside),
            "--out",
            s(&poses),
        ],
        "malformed CSV row",
    );
}

/// Facings of another convention: measured from the y axis (facing_rad + 90°) gave 162 of 200
/// `ok` poses, 10 beyond 5σ and up to 3.4 m off; reversed (into the walls) 7 `ok`, all 5 m
/// and 180° off, both with exit 0. Both are refused naming the quarter turns to add; the map
/// as made localises (`cli_synth_then_localize_with_truth`).
#[test]
fn cli_facings_of_another_convention_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    synth_lrf(d, 1, 200);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.json")).expect("map"))
            .expect("json");
    let scans = d.join("scans.csv");
    let poses = d.join("poses.csv");
    for (name, turn, want) in [
        (
            "f90.json",
            std::f64::consts::FRAC_PI_2,
            "add -1.5708 rad (-90°) to every facing_rad (measured from the y axis, or clockwise?)",
        ),
        (
            "flip.json",
            std::f64::consts::PI,
            "add -3.1416 rad (-180°) to every facing_rad (they point into the walls)",
        ),
    ] {
        let landmarks: Vec<serde_json::Value> = m["landmarks"]
            .as_array()
            .expect("landmarks")
            .iter()
            .map(|l| {
                let f = l["facing_rad"].as_f64().expect("facing_rad") + turn;
                let f = odocal_core::wrap_angle(f);
                serde_json::json!({"id": l["id"], "x_m": l["x_m"], "y_m": l["y_m"], "facing_rad": f})
            })
            .collect();
        let map = d.join(name);
        let json = serde_json::json!({"format": m["format"], "landmarks": landmarks});
        std::fs::write(&map, json.to_string()).expect("write map");
        let e = expect_error(
            &[
                "lrf",
                "localize",
                "--map",
                s(&map),
                s(&scans),
                "--out",
                s(&poses),
            ],
            "left out 90 of the first 100 find one",
        );
        assert!(e.contains(want), "{name}: {e}");
        assert!(!poses.exists());
    }
}
