//! `odocal synth lrf`: a landmark map, a sensor trajectory and laser scans with known truth.

use std::path::PathBuf;

use odocal_synth::lrf_sim::{simulate, LrfSimConfig};

use crate::output::{check_synth_files, commit, write_atomic, SYNTH_MARK, SYNTH_MARK_TEXT};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Output directory (map.json, scans.csv, truth.csv).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of landmarks (rooms for more than 30 grow to keep the density of 30 in 10 m × 8 m).
    #[arg(long, default_value_t = 30)]
    pub landmarks: usize,
    /// Random seed (same seed, same files).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of scans (10 Hz).
    #[arg(long, default_value_t = 300)]
    pub scans: usize,
    /// Place landmarks in pairs symmetric under a 180° turn about the room centre (deliberately ambiguous).
    #[arg(long)]
    pub symmetric: bool,
    /// Time from a scan's first beam to its last, seconds; each beam is cast from the pose at
    /// its time. Default: one turn per scan (240° at 10 Hz: 67 ms), as `lrf localize` assumes;
    /// 0: all beams from the scan's pose (localise those with `--sweep-s 0`).
    #[arg(long)]
    pub sweep_s: Option<f64>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.landmarks < 3 || args.landmarks > 5000 {
        anyhow::bail!("--landmarks {} must be between 3 and 5000", args.landmarks);
    }
    if args.scans == 0 {
        anyhow::bail!("--scans must be at least 1");
    }
    super::synth_count_at_most(args.scans, "--scans", 1_000_000, "28 hours at 10 Hz")?;
    if args.symmetric && args.landmarks % 2 == 1 {
        anyhow::bail!(
            "--landmarks {} with --symmetric: a symmetric layout places landmarks in pairs; give an even number",
            args.landmarks
        );
    }
    let mut cfg = LrfSimConfig {
        symmetric: args.symmetric,
        n_scans: args.scans,
        ..LrfSimConfig::scaled(args.landmarks, args.seed)
    };
    cfg.sweep_s = match args.sweep_s {
        Some(s) if !(s.is_finite() && (0.0..=1.0 / cfg.rate_hz).contains(&s)) => anyhow::bail!(
            "--sweep-s {s}: need a time from the first beam to the last in [0, {}] s (one scan at {} Hz)",
            1.0 / cfg.rate_hz,
            cfg.rate_hz
        ),
        Some(s) => s,
        None => cfg.turn_share_s(),
    };
    let sim = simulate(&cfg);
    // The room keeps free space for the path and between landmarks: a crowded one fills up.
    if sim.world.landmarks.len() < args.landmarks {
        anyhow::bail!(
            "could only place {} of the {} landmarks in the {:.1} m x {:.1} m room (they keep apart and off the path); ask for fewer",
            sim.world.landmarks.len(),
            args.landmarks,
            cfg.room_w_m,
            cfg.room_h_m
        );
    }
    let map = args.out.join("map.json");
    let scans = args.out.join("scans.csv");
    let truth = args.out.join("truth.csv");
    check_synth_files(&args.out, &["map.json", "scans.csv", "truth.csv"], "--out")?;
    write_atomic(&args.out.join(SYNTH_MARK), SYNTH_MARK_TEXT)?;
    write_atomic(&map, sim.map_json().as_bytes())?;
    write_atomic(&scans, sim.scans_csv().as_bytes())?;
    write_atomic(&truth, sim.truth_csv().as_bytes())?;
    let (det, spur, missed) = sim.summary();
    say!(
        "synth lrf: {} landmarks in {:.1} m x {:.1} m{}, {} scans; per scan {:.1} reflectors detected, {:.1} spurious ({:.0} %), {:.0} % missed; sigma_range {:.0} mm",
        sim.world.landmarks.len(),
        cfg.room_w_m,
        cfg.room_h_m,
        if cfg.symmetric { " (symmetric layout)" } else { "" },
        sim.scans.len(),
        det,
        spur,
        100.0 * spur / det.max(1e-9),
        100.0 * missed,
        cfg.sigma_range_m * 1e3
    );
    commit()?;
    say!(
        "wrote {}, {}, {}\nnext: odocal lrf localize --map {} {} --out poses.csv --truth {}",
        map.display(),
        scans.display(),
        truth.display(),
        map.display(),
        scans.display(),
        truth.display()
    );
    Ok(())
}
