//! Benchmark: laser positioning per scan, N = 30 and N = 200 landmarks.
//! Global localisation (sorted edges + binary search + grid) against a
//! brute-force association on the same scans (every landmark pair's distance
//! compared, every landmark scanned), the source's chained search, and
//! tracking. Prints median times per scan and the ratios.
//! Run: `cargo bench --bench lrf` (release).

use std::time::{Duration, Instant};

use odocal_lrf::{Detection, Localizer, LocalizerConfig, Map, Scan, ScanTracker, Status};
use odocal_synth::lrf_sim::{simulate, LrfSimConfig};

/// Median over `reps` runs of `f`'s time divided by `per`.
fn median_per(reps: usize, per: usize, mut f: impl FnMut()) -> Duration {
    let mut v: Vec<Duration> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed() / per.max(1) as u32
        })
        .collect();
    v.sort();
    v[v.len() / 2]
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn main() {
    println!("lrf benchmark: per-scan times (median of repetitions), release build");
    for n in [30usize, 200] {
        // 300 scans at 1 m/s: a long stretch of the loop (a whole loop at N = 30).
        let cfg = LrfSimConfig {
            n_scans: 300,
            speed_mps: 1.0,
            ..LrfSimConfig::scaled(n, 7)
        };
        let sim = simulate(&cfg);
        let map = match Map::parse(&sim.map_json(), "sim") {
            Ok(m) => m,
            Err(e) => {
                eprintln!("simulated map invalid: {e}");
                return;
            }
        };
        let loc = Localizer::new(map, LocalizerConfig::default());
        let scans: Vec<Scan> = sim
            .scans
            .iter()
            .map(|s| Scan {
                id: s.id,
                t_s: Some(s.t_s),
                angles_rad: s.angles_rad.clone(),
                ranges_m: s.ranges_m.clone(),
                intensities: s.intensities.clone(),
                reversed: false,
            })
            .collect();
        let dets: Vec<Vec<Detection>> = scans.iter().map(|s| loc.detections(s)).collect();
        let k = scans.len();
        let eligible = sim.scans.iter().filter(|s| s.n_detected >= 3).count();
        let mean_dets = dets.iter().map(|d| d.len()).sum::<usize>() as f64 / k as f64;
        println!(
            "\nN = {n} landmarks, room {:.1} m x {:.1} m, {k} scans ({eligible} with >= 3 reflectors detected), {mean_dets:.1} detections/scan",
            cfg.room_w_m, cfg.room_h_m
        );

        let t_extract = median_per(7, k, || {
            for s in &scans {
                std::hint::black_box(loc.detections(s));
            }
        });
        let mut n_ok = 0;
        let t_global = median_per(5, k, || {
            n_ok = 0;
            for (s, d) in scans.iter().zip(&dets) {
                if loc.global(s, d).status == Status::Ok {
                    n_ok += 1;
                }
            }
        });
        let mut n_ok_bf = 0;
        let bf_scans = if n > 50 { 50 } else { k };
        let t_brute = median_per(3, bf_scans, || {
            n_ok_bf = 0;
            for (s, d) in scans.iter().zip(&dets).take(bf_scans) {
                if loc.global_brute_force(s, d).status == Status::Ok {
                    n_ok_bf += 1;
                }
            }
        });
        // Global on exactly the scans the brute force ran on, for the ratio.
        let t_global_same = median_per(5, bf_scans, || {
            for (s, d) in scans.iter().zip(&dets).take(bf_scans) {
                std::hint::black_box(loc.global(s, d));
            }
        });
        let mut n_src = 0;
        let t_source = median_per(5, k, || {
            n_src = 0;
            for d in &dets {
                if !loc.source_search(d).is_empty() {
                    n_src += 1;
                }
            }
        });
        let mut n_track_ok = 0;
        let mut n_track_mode = 0;
        let t_track = median_per(5, k, || {
            let mut tr = ScanTracker::new(&loc);
            n_track_ok = 0;
            n_track_mode = 0;
            for s in &scans {
                let r = tr.process(s, s.t_s.unwrap_or(0.0));
                n_track_ok += (r.status == Status::Ok) as usize;
                n_track_mode += (r.mode == "track") as usize;
            }
        });
        println!(
            "  cluster detections          {:9.1} µs/scan",
            us(t_extract)
        );
        println!(
            "  global (sorted edges)       {:9.1} µs/scan   ok {n_ok}/{k}   target < 1000 µs at N = 200",
            us(t_global)
        );
        println!(
            "  global brute force          {:9.1} µs/scan   ok {n_ok_bf}/{bf_scans}   ratio brute/global on the same {bf_scans} scans {:.1}x ({:.1} µs)",
            us(t_brute),
            us(t_brute) / us(t_global_same),
            us(t_global_same)
        );
        println!(
            "  source chained search       {:9.1} µs/scan   all detections matched on {n_src}/{k} scans (fails with spurious returns)",
            us(t_source)
        );
        println!(
            "  tracking (whole scan)       {:9.1} µs/scan   ok {n_track_ok}/{k}, {n_track_mode} in tracking mode   target < 50 µs at N = 200; ratio global/tracking {:.1}x",
            us(t_track),
            us(t_global) / us(t_track)
        );
    }
}
