//! `odocal lrf`: laser positioning among reflective landmarks.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use odocal_lrf::{
    check_beam_step, check_fov, check_intensity_scale, check_map_report, check_range_unit,
    check_scan_times, drop_beyond_range, evaluate, facings_hide_poses, layout_repeats,
    localize_scans, mirror_fits_better, mirrored_finds_poses, read_scan_files, read_truth_csv,
    wider_noise_finds_poses, Localized, Localizer, LocalizerConfig, Map, ScanFiles, SensorConfig,
    Skewed, Status, DEFAULT_TOLERANCE_M, HULL_MARGIN_M,
};

use crate::output::{check_output_file, commit, progress, write_atomic};

/// Subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Validate a landmark map and report ambiguous (congruent or mirror-image) sub-configurations.
    CheckMap(CheckMapArgs),
    /// Localise laser scans against a landmark map and write the sensor poses.
    Localize(LocalizeArgs),
}

/// Arguments of `odocal lrf check-map`.
#[derive(clap::Args)]
pub struct CheckMapArgs {
    /// The landmark map (JSON, "format": "odocal.lrf-map/1").
    pub map: PathBuf,
    /// Two configurations match if every landmark is within this distance, metres.
    #[arg(long, default_value_t = DEFAULT_TOLERANCE_M)]
    pub tolerance_m: f64,
    /// Sensor range: only landmarks seen together (within this of each other's midpoint) count, metres.
    #[arg(long, default_value_t = 5.6)]
    pub max_range_m: f64,
    /// Report configurations of at least this many landmarks.
    #[arg(long, default_value_t = 3)]
    pub min_size: usize,
}

/// Arguments of `odocal lrf localize`.
#[derive(clap::Args)]
pub struct LocalizeArgs {
    /// The landmark map (JSON, "format": "odocal.lrf-map/1").
    #[arg(long)]
    pub map: PathBuf,
    /// Scan CSV files (`angle,range,intensity`, optionally `scan,t`): with t, taken in time order;
    /// without, taken in natural name order (scan2.csv before scan10.csv).
    #[arg(required = true)]
    pub scans: Vec<PathBuf>,
    /// Output CSV: t,x,y,theta,status,n_landmarks,n_detections,n_hypotheses,score,mode,scan (x,y,theta empty when lost).
    /// score: landmarks matched minus landmarks in view from the pose that were not detected
    /// (a count, no unit; 0 when lost; an `ok` pose has at least 1).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the `ok` poses as a trajectory CSV
    /// (`t,x,y,theta,quality,sigma_x,sigma_y,sigma_theta`, σ from each pose's Cramér–Rao
    /// bound): the laser's ground truth in the format `odocal dataset` and `odocal evaluate`
    /// read from a manifest.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// True poses (CSV t,x,y,theta[,n_detected]) to report the error against.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Localise every scan on its own (no tracking, no history).
    #[arg(long)]
    pub global_only: bool,
    /// Range noise of the scanner (1 sigma), metres.
    #[arg(long, default_value_t = 0.01)]
    pub sigma_range_m: f64,
    /// Maximum range of the scanner, metres.
    #[arg(long, default_value_t = 5.6)]
    pub max_range_m: f64,
    /// Field of view of the scanner, degrees.
    #[arg(long, default_value_t = 240.0)]
    pub fov_deg: f64,
    /// Returns at or above this intensity are reflector candidates (the scans' intensity
    /// column, 0 to 1 as `synth lrf` writes it; a scanner's raw counts need a threshold on
    /// their own scale).
    #[arg(long, default_value_t = 0.5)]
    pub intensity_min: f64,
    /// Scan rate of the scanner, Hz: the times of files without a `t` column, the check that
    /// the scans' times are in seconds and, without --sweep-s, the sweep's time (scans whose
    /// spacing is not a whole number of its periods are refused).
    #[arg(long, default_value_t = 10.0)]
    pub rate_hz: f64,
    /// Time from a scan's first beam to its last, seconds. By default a turn takes 1/--rate-hz
    /// and the beams span their share of it (240° at 10 Hz: 67 ms); give the scanner's own
    /// time when its mirror turns faster than it sends scans, 0 when it takes all beams at once.
    /// A scan's time is its first beam's; its beams are de-skewed with the tracked motion.
    #[arg(long)]
    pub sweep_s: Option<f64>,
    /// The scanner is mounted upside down: its angles run clockwise seen from above, and every
    /// angle is negated before localising (the poses are the scanner's, its x axis along the
    /// 0 rad beam).
    #[arg(long)]
    pub upside_down: bool,
}

/// Runs a subcommand.
pub fn run(cmd: Command) -> anyhow::Result<()> {
    match cmd {
        Command::CheckMap(a) => check_map(a),
        Command::Localize(a) => localize(a),
    }
}

fn check_map(a: CheckMapArgs) -> anyhow::Result<()> {
    let map = Map::read(&a.map)?;
    let name = a.map.display().to_string();
    for line in check_map_report(&map, &name, a.tolerance_m, a.max_range_m, a.min_size)? {
        say!("{line}");
        // The verdict is the report's last line; an ambiguous one is said on stderr too, as
        // every result that needs attention is.
        if let Some(verdict) = line.strip_prefix("verdict: AMBIGUOUS") {
            tell!("warning: {name}: AMBIGUOUS{verdict}");
        }
    }
    warn_isolated(&map, &name, a.max_range_m);
    Ok(())
}

/// Warns of every landmark that no scan sees with another: far from all the others, its
/// coordinates are most likely mistyped.
fn warn_isolated(map: &Map, name: &str, max_range_m: f64) {
    let isolated = map.isolated(max_range_m);
    // Many landmarks alone are no typos: the range given is shorter than the room's spacing
    // (`--max-range-m 0.5` named 10 landmarks as mistyped, one by one, before anything else).
    if isolated.len() >= 3 && isolated.len() * 5 >= map.len() {
        let mut gaps: Vec<f64> = isolated.iter().map(|x| x.2).collect();
        gaps.sort_by(f64::total_cmp);
        tell!(
            "warning: {name}: {} of its {} landmarks are more than twice --max-range-m {max_range_m} m from every other (the nearest other {:.2} m away, median), so no scan sees them with another: is --max-range-m the scanner's range (its data sheet's), in metres?",
            isolated.len(),
            map.len(),
            gaps[gaps.len() / 2]
        );
        return;
    }
    for (id, p, nearest) in isolated {
        tell!(
            "warning: {name}: landmark id {id} at ({:.3}, {:.3}) m is {nearest:.2} m from the nearest other landmark, more than twice --max-range-m {max_range_m} m, so no scan sees it with another and it cannot help a pose: is a coordinate mistyped?",
            p.x, p.y
        );
    }
}

/// Warns of poses left with their sweep's skew whose σ had to be widened for it.
fn warn_skewed(w: &Skewed, global_only: bool) {
    let (m, rad) = w.max_sweep_motion;
    let cause = if global_only {
        "--global-only localises each scan on its own, with no tracked motion to de-skew its beams by; drop it to de-skew them"
    } else {
        "no motion was tracked yet for them (the first scans of a track)"
    };
    tell!(
        "warning: {} of {} poses were not de-skewed and the sensor moved up to {:.1} mm and {:.2}° during their sweeps: their σ were widened by half a sweep's motion ({cause}; if the scanner takes all beams at once, give --sweep-s 0)",
        w.n_widened,
        w.n_poses,
        m * 1e3,
        rad.to_degrees()
    );
}

fn localize(a: LocalizeArgs) -> anyhow::Result<()> {
    check_output_file(&a.out, "--out")?;
    if let Some(p) = &a.trajectory {
        check_output_file(p, "--trajectory")?;
    }
    let mut cfg = LocalizerConfig {
        sensor: SensorConfig {
            fov_rad: a.fov_deg.to_radians(),
            max_range_m: a.max_range_m,
            sigma_range_m: a.sigma_range_m,
            intensity_min: a.intensity_min,
            rate_hz: a.rate_hz,
            sweep_s: a.sweep_s,
            ..SensorConfig::default()
        },
        ..LocalizerConfig::default()
    };
    // The options are checked before any file is read, the scans' step after.
    cfg.sensor.check()?;
    let map = Map::read(&a.map)?;
    warn_isolated(&map, &a.map.display().to_string(), a.max_range_m);
    let ScanFiles {
        mut scans,
        step_rad,
        reversed_note,
        numbered_by_name,
        truncated_notes,
    } = read_scan_files(&a.scans)?;
    if let Some(note) = reversed_note {
        tell!("note: {note}");
    }
    for w in truncated_notes {
        tell!("warning: {w}");
    }
    if a.upside_down {
        for s in &mut scans {
            *s = s.mirrored();
        }
    }
    check_range_unit(&scans, a.max_range_m)?;
    drop_beyond_range(&mut scans, a.max_range_m);
    let periods_apart = check_scan_times(&scans, &cfg.sensor)?;
    // A scanner that many times slower gives the same times with a longer sweep: said, as
    // only the user knows which it is.
    let slower_rate = (periods_apart > 1 && a.sweep_s.is_none()).then(|| {
        let slower_hz = (a.rate_hz / f64::from(periods_apart) * 1e3).round() / 1e3;
        tell!(
            "note: the scans are {periods_apart} periods of --rate-hz {} apart (median), read as one scan kept in {periods_apart} of a {} Hz scanner's; if the scanner itself runs at {slower_hz} Hz, give --rate-hz {slower_hz}, or its sweep is taken {periods_apart} times too short",
            a.rate_hz,
            a.rate_hz
        );
        slower_hz
    });
    if let Some(step) = step_rad {
        cfg.sensor.step_rad = step;
    }
    cfg.sensor.check()?;
    check_fov(&scans, &cfg.sensor)?;
    check_intensity_scale(&scans, &cfg.sensor)?;
    // Untimed scans are timed by their ids: a gap in them is scans dropped, said so.
    if scans.iter().all(|s| s.t_s.is_none()) && scans.windows(2).all(|w| w[0].id < w[1].id) {
        if let (Some(first), Some(last)) = (scans.first(), scans.last()) {
            let missing = (last.id - first.id + 1) as usize - scans.len();
            if missing > 0 && numbered_by_name {
                // Few are listed, so the user can look for those files.
                let gaps: Vec<String> = scans
                    .windows(2)
                    .filter(|w| w[1].id > w[0].id + 1)
                    .map(|w| match (w[0].id + 1, w[1].id - 1) {
                        (a, b) if a == b => a.to_string(),
                        (a, b) => format!("{a}–{b}"),
                    })
                    .collect();
                let which = if gaps.len() <= 10 {
                    format!(" ({})", gaps.join(", "))
                } else {
                    String::new()
                };
                tell!(
                    "note: the scan files have no t column and {missing} of the numbers in their names from {} to {} are missing{which}: each scan is timed by its file's number at --rate-hz {} (a number skipped is a scan dropped), so the motion between the scans either side of a gap is that of the time it spans; give each scan's time in a t column if the numbers do not count the scanner's sweeps",
                    first.id,
                    last.id,
                    a.rate_hz
                );
            } else if missing > 0 {
                tell!(
                    "note: the scans have no t column and {missing} of the scan ids from {} to {} are missing: each scan is timed by its id at --rate-hz {} (a gap is scans dropped), so the motion between the scans either side of a gap is that of the time it spans; give each scan's time in a t column if the ids do not count the scanner's sweeps",
                    first.id,
                    last.id,
                    a.rate_hz
                );
            }
        }
    }
    let loc = Localizer::new(map, cfg);
    if let Some(w) = check_beam_step(&loc, &scans) {
        tell!("warning: {w}");
    }
    let bar = progress(scans.len() as u64, "localize");
    let start = Instant::now();
    let Localized {
        log,
        skewed,
        n_repeated,
        unseen,
        dim,
        moved,
        n_unsupported,
        fit,
        calibration,
        left_out,
        n_off_track,
    } = localize_scans(&loc, &scans, a.rate_hz, a.global_only, &|| bar.inc(1));
    let elapsed = start.elapsed();
    bar.finish_and_clear();
    // A repeated scan was not localised: it counts as no lost scan, and its detections (none
    // looked for) in no rate, or a driver republishing its scans read as a wrong map.
    let count = |s: Status| {
        log.rows
            .iter()
            .filter(|r| r.status == s && r.mode != "repeated")
            .count()
    };
    let n_judged = log.rows.len() - n_repeated;
    let scans_judged = match (n_judged, n_repeated) {
        (1, 0) => "1 scan".to_string(),
        (n, 0) => format!("{n} scans"),
        (1, r) => format!("1 scan ({r} repeated aside)"),
        (n, r) => format!("{n} scans ({r} repeated aside)"),
    };
    // Scans mirrored that find poses where as given they fit the map nowhere: the scanner's
    // angles run the other way round. Refused before any other word, as every scan's fit
    // (and every warning drawn from it) is wrong, and the few poses found are coincidences.
    if count(Status::Lost) * 2 > n_judged {
        if let Some(m) = mirrored_finds_poses(&loc, &scans, a.rate_hz, a.global_only) {
            let (looks, fix) = if a.upside_down {
                (
                    "the scanner looks mounted the right way up, its angles counter-clockwise as they are",
                    "drop --upside-down",
                )
            } else {
                // Scans and map mirrored to each other look the same whichever is: the map's
                // frame may be the left-handed one (y flipped), which --upside-down would only
                // mirror the poses into.
                (
                    "the scanner looks mounted upside down, its angles clockwise",
                    "give --upside-down (which negates every angle), or turn the scanner the right way up; or, if the scanner is the right way up, the map is a mirror image of the room (its y axis flipped, a left-handed frame): give the map with y and facing_rad negated",
                )
            };
            anyhow::bail!(
                "{} of {} found no pose, and with their angles mirrored {} of the first {} find one, where {} did: {looks}, so nothing was written; {fix}",
                count(Status::Lost),
                scans_judged,
                m.n_ok_mirrored,
                m.n_scans,
                m.n_ok_given
            );
        }
    }
    // Most scans found a pose, but away from every landmark, and the scans mirrored fit among
    // them: a map of landmarks alone mirrored to the room (y flipped, x and y swapped) gave
    // 232 of 300 scans `ok`, 12 m off, with exit 0.
    if let Some(m) = mirror_fits_better(&loc, &scans, a.rate_hz, a.global_only, &log) {
        let scanner = if a.upside_down {
            "if the scanner is the right way up, drop --upside-down"
        } else {
            "if the scanner is mounted upside down (its angles clockwise), give --upside-down"
        };
        anyhow::bail!(
            "{} of the {} ok poses lie outside the landmarks of {} (by more than {} m), and with their angles mirrored {} of the first {} scans find a pose, {} of them among the landmarks, where as given {} found one there: the scans and the map are mirror images of each other, so nothing was written; {scanner}; else the map is a mirror image of the room (its y axis flipped, a left-handed frame, or x and y swapped, northing before easting): give it with y and facing_rad negated, or x and y swapped back",
            m.n_outside_given,
            m.n_ok_given,
            a.map.display(),
            HULL_MARGIN_M,
            m.n_ok_mirrored,
            m.n_scans,
            m.n_ok_mirrored - m.n_outside_mirrored,
            m.n_ok_first - m.n_outside_first,
        );
    }
    // Facings of another convention hide the landmarks where the scanner sees them: tried
    // whenever a twentieth of the scans or more found no pose.
    if count(Status::Ok) * 20 < n_judged * 19 {
        if let Some(f) = facings_hide_poses(&loc, &scans, a.rate_hz, a.global_only, &log) {
            let deg = f.offset_rad.to_degrees();
            // Conventions differ by quarter turns; the mean itself is pulled towards 0 by
            // landmarks in range the scanner did not see (-69° for facings 90° off).
            let quarter = std::f64::consts::FRAC_PI_2;
            let turn = (f.offset_rad / quarter).round() * quarter;
            anyhow::bail!(
                "{} of {} found a pose, and with the facing_rad of {} left out {} of the first {} find one, where {} did: the scanner sees the landmarks from about {:.0}° off the way their facing_rad says they face (mean over the landmarks in range at those poses, more than 45° off), so nothing was written; facing_rad is the direction a reflector faces, into the room, in radians counter-clockwise from the map's x axis: add {:.4} rad ({:.0}°) to every facing_rad{}, or leave facing_rad out",
                count(Status::Ok),
                scans_judged,
                a.map.display(),
                f.n_ok_free,
                f.n_scans,
                f.n_ok_given,
                deg,
                turn,
                turn.to_degrees(),
                if deg.abs() > 135.0 {
                    " (they point into the walls)"
                } else if deg.abs() > 45.0 {
                    " (measured from the y axis, or clockwise?)"
                } else {
                    ""
                }
            );
        }
    }
    let why_lost = || {
        format!(
            "is {} the map of this room, in metres, and are the scanner's angles counter-clockwise (a scanner mounted upside down mirrors them)? Check --intensity-min {} against the reflectors' returns and --max-range-m {} m",
            a.map.display(),
            a.intensity_min,
            a.max_range_m
        )
    };
    // Said first: the landmarks, poses and counts below are of the corrected scans.
    if let Some(c) = calibration {
        let (_, sb) = c.residual.range_offset_m;
        let (_, sk) = c.residual.angle_scale;
        let mut found = Vec::new();
        if c.range_offset_m.abs() >= 1e-3 {
            found.push(format!(
                "the ranges read {:.1} ± {:.1} mm {}",
                c.range_offset_m.abs() * 1e3,
                sb * 1e3,
                if c.range_offset_m > 0.0 {
                    "long"
                } else {
                    "short"
                }
            ));
        }
        if (c.angle_scale - 1.0).abs() >= 2e-4 {
            found.push(format!(
                "the angles read {:.5} ± {:.5} times the true ones (an angle step of {:.7} rad, where the scans step {:.7} rad)",
                c.angle_scale,
                sk,
                loc.cfg.sensor.step_rad / c.angle_scale,
                loc.cfg.sensor.step_rad
            ));
        }
        tell!(
            "warning: the landmarks' residuals were {:.1} times the detections' noise (χ² per degree of freedom), off alike at every landmark as a miscalibrated scanner leaves them: fitted over the recording, {}; every range and angle was corrected by that and the scans localised again (χ² per degree of freedom now {:.2}). Calibrate the scanner (its range offset, the angle_increment its driver reports), or give the scans corrected",
            c.ratio_before,
            found.join(" and "),
            c.ratio_after
        );
    }
    // Said before any refusal: a reflector gone from a symmetric room leaves every scan
    // ambiguous.
    for &(id, n, missed) in &unseen {
        // A reflector that returns at its place, only dimly, is there: the threshold is.
        if let Some(&(_, n_dim, median)) = dim.iter().find(|d| d.0 == id) {
            tell!(
                "warning: landmark {id} of {} was in view in {n} scans and not seen in {missed} of them, but in {n_dim} of those a return lay at its place, at intensity {median:.3} (median), below --intensity-min {}: is the reflector there and its returns dimmer than the threshold (far, or seen at a slant)? Give --intensity-min below {median:.3} if the walls stay under it",
                a.map.display(),
                a.intensity_min
            );
            continue;
        }
        // A map without facings takes every reflector for visible from all sides: one on a
        // wall seen from behind it was called gone, and removing it loses a good landmark.
        let facing_hint = if loc
            .map
            .landmarks
            .iter()
            .any(|l| l.id == id && l.facing.is_none())
        {
            "; if it is there, on a wall or post that hides it from some side, give its facing_rad (the direction it faces, radians) so that it is expected only where it can be seen"
        } else {
            ""
        };
        tell!(
            "warning: landmark {id} of {} was in view in {n} scans and not seen in {missed} of them: is it still there? A mapped reflector that is gone (fallen off, covered) counts against the right pose alone, and in a symmetric layout it leaves the scans ambiguous; put it back, or remove it from the map{facing_hint}",
            a.map.display()
        );
    }
    // Beams timed wrongly bias every landmark they see moving: the other cause to name.
    let mistimed = match (a.sweep_s, slower_rate) {
        (Some(_), _) => "a scanner whose beams are not timed as --sweep-s says biases the landmarks too".to_string(),
        (None, Some(hz)) => format!("a scanner slower than --rate-hz {} biases the landmarks too: if it runs at {hz} Hz, give --rate-hz {hz}", a.rate_hz),
        (None, None) => format!("a scanner whose rate is not --rate-hz {}, or whose mirror turns faster than it sends scans (give --sweep-s), biases the landmarks too", a.rate_hz),
    };
    // Whether the χ² warning below has landmarks above to point at.
    let named = !moved.is_empty() || !left_out.is_empty();
    for m in moved {
        let dir = m.offset_m.normalize();
        tell!(
            "warning: landmark {} of {} sits {:.0} mm from its mapped position along ({:.2}, {:.2}) in {} scans from {} (σ of that mean {:.1} mm): was it moved after mapping? Every scan was localised again with the map without it (the poses it had pulled, and the motion the sweeps are de-skewed with, freed of it); update its position in {}, or remove it ({mistimed})",
            m.id,
            a.map.display(),
            m.offset_m.norm() * 1e3,
            dir.x,
            dir.y,
            m.n_scans,
            if m.n_places == 1 {
                "one place".to_string()
            } else {
                format!("{} places", m.n_places)
            },
            m.sigma_m * 1e3,
            a.map.display()
        );
    }
    // Poses that fit their landmarks worse than the noise explains: more than chance would
    // make (1 % of them, and three standard deviations of that count) is a cause to find.
    let by_chance = 0.01 * fit.n_poses as f64;
    if fit.n_widened as f64 > by_chance + 3.0 * by_chance.sqrt() + 1.0 {
        // With no landmark to blame, residuals χ² times their noise all over are a range
        // noise √χ² times the one given (4 cm noise at --sigma-range-m 0.01 gave χ² 3.76,
        // 19 mm): named as a figure the user can give, or check against the datasheet.
        let cause = if named {
            "A landmark off its mapped place (moved, or surveyed wrong) or a shiny object taken for a reflector does this: check the landmarks named above, the map's position_sigma_m and --sigma-range-m".to_string()
        } else {
            let implied = a.sigma_range_m * fit.ratio.max(1.0).sqrt();
            format!(
                "No landmark sits off its place, so the detections are noisier than --sigma-range-m {} m says: the residuals imply a range noise of about {:.0} mm (1σ, --sigma-range-m times √χ² per degree of freedom); if the scanner's datasheet or the spread of its ranges to a wall agree, give --sigma-range-m {:.3}, else look for a shiny object taken for a reflector or a map surveyed coarser than its position_sigma_m",
                a.sigma_range_m,
                implied * 1e3,
                implied
            )
        };
        tell!(
            "warning: {} of {} ok poses fit their landmarks worse than the detections' noise explains (χ² beyond its 99 % quantile, where about {:.0} would by chance; over the recording χ² is {:.2} times its degrees of freedom): their σ were widened by that excess and by how far leaving out each landmark moves the pose. {cause}",
            fit.n_widened,
            fit.n_poses,
            by_chance,
            fit.ratio
        );
    }
    for m in left_out {
        let dir = m.offset_m.normalize();
        tell!(
            "warning: landmark {} of {} was detected {:.0} mm from its mapped position along ({:.2}, {:.2}) in {} scans (σ of that mean {:.1} mm), too far to fit, and was left out of their poses each time: was it moved after mapping? Update its position in {}, or remove it",
            m.id,
            a.map.display(),
            m.offset_m.norm() * 1e3,
            dir.x,
            dir.y,
            m.n_scans,
            m.sigma_m * 1e3,
            a.map.display()
        );
    }
    if n_off_track > 0 {
        tell!(
            "warning: {n_off_track} ok {} off the track the poses either side give by more than {} σ and a small robot's acceleration allow: {} widened to cover how far off {} (a shiny object taken for a reflector in place of one can fit as well as the right landmarks); check the scans at those times for glints, or raise --intensity-min",
            if n_off_track == 1 { "pose lay" } else { "poses lay" },
            if n_off_track == 1 { "its" } else { "their" },
            if n_off_track == 1 { "its σ was" } else { "their σ were" },
            if n_off_track == 1 { "it is" } else { "they are" },
        );
    }
    // A range noise given too small turns the true poses away and reads like a wrong map:
    // tried first, on the run's first scans, whenever most scans found no pose.
    let noise_hint = || {
        wider_noise_finds_poses(&loc, &scans, a.rate_hz, a.global_only).map(|w| {
            let (times, why) = if w.sigma_range_m > a.sigma_range_m {
                (
                    format!("{:.0} times", w.sigma_range_m / a.sigma_range_m),
                    "a σ below the scanner's range noise turns the true pose away",
                )
            } else {
                (
                    format!("1/{:.0} of", a.sigma_range_m / w.sigma_range_m),
                    "a σ far above the scanner's range noise lets every scan fit the map in several places",
                )
            };
            format!(
                "with --sigma-range-m {} m ({times} the {} m given) {} of the first {} scans find a pose, where {} did: matches are gated at a few σ of --sigma-range-m, so {why}; give the scanner's range noise (1σ, from its datasheet or the spread of its ranges to a wall)",
                w.sigma_range_m,
                a.sigma_range_m,
                w.n_ok_wider,
                w.n_scans,
                w.n_ok_given
            )
        })
    };
    // A file without one `ok` row is no result: refused, as `track` refuses a video where
    // the tag was never accepted.
    if !log.rows.is_empty() && count(Status::Ok) == 0 {
        let detections: usize = log.rows.iter().map(|r| r.n_detections).sum();
        let per_scan = detections as f64 / n_judged.max(1) as f64;
        if let Some(hint) = noise_hint() {
            anyhow::bail!(
                "none of the {} found a pose ({} ambiguous, {} lost; {per_scan:.1} reflector detections per scan), so {} was not written: {hint}",
                scans_judged,
                count(Status::Ambiguous),
                count(Status::Lost),
                a.out.display()
            );
        }
        if count(Status::Lost) == n_judged {
            anyhow::bail!(
                "none of the {} found a pose ({per_scan:.1} reflector detections per scan), so {} was not written: {}",
                scans_judged,
                a.out.display(),
                why_lost()
            );
        }
        // Ambiguous scans of a map with no congruent configuration fit it nowhere well: the
        // scans are of another room, or read wrongly, not of a symmetric layout.
        if !layout_repeats(&loc.map, a.max_range_m) {
            anyhow::bail!(
                "none of the {} found a pose ({} ambiguous, {} lost; {per_scan:.1} reflector detections per scan), so {} was not written; {} has no congruent configuration (`odocal lrf check-map {}`), so no symmetric layout explains the ambiguous ones: {}",
                scans_judged,
                count(Status::Ambiguous),
                count(Status::Lost),
                a.out.display(),
                a.map.display(),
                a.map.display(),
                why_lost()
            );
        }
        // A mapped reflector never seen is the likely cause: with it gone the room repeats
        // itself, and adding a landmark would leave the gone one in the map.
        if let Some(&(id, n, missed)) = unseen.first() {
            let at = loc
                .map
                .landmarks
                .iter()
                .find(|l| l.id == id)
                .map_or_else(String::new, |l| {
                    format!(" at ({:.2}, {:.2}) m", l.position.x, l.position.y)
                });
            anyhow::bail!(
                "none of the {} found a pose it could tell from another ({} ambiguous, {} lost; {per_scan:.1} reflector detections per scan), so nothing was written: landmark {id}{at} of {} was not seen in {missed} of the {n} scans it should have been in view in; with it gone the landmarks repeat themselves (a symmetric layout); put it back, or remove it from the map and add one that breaks the symmetry (`odocal lrf check-map {}`)",
                scans_judged,
                count(Status::Ambiguous),
                count(Status::Lost),
                a.map.display(),
                a.map.display()
            );
        }
        // Ambiguous scans fit the map in several places equally well: the layout repeats
        // itself where the scanner went, which no setting of the scanner changes.
        anyhow::bail!(
            "none of the {} found a pose it could tell from another ({} ambiguous, {} lost; {per_scan:.1} reflector detections per scan): the landmarks of {} repeat themselves (a symmetric layout), so every scan fits several places and nothing was written; run `odocal lrf check-map {}` and add or move a landmark to break the symmetry",
            scans_judged,
            count(Status::Ambiguous),
            count(Status::Lost),
            a.map.display(),
            a.map.display()
        );
    }
    // The truth is read and compared first: poses it shows to be wrong are not written.
    let against = match &a.truth {
        Some(tp) => {
            let truth = read_truth_csv(tp).with_context(|| "reading the truth file".to_string())?;
            let e = evaluate(&log.for_evaluation(), &truth);
            if e.n_scans == 0 {
                anyhow::bail!(
                    "{}: no truth pose has the time of a scan, nor are two truth rows at most {:.0} ms apart around one; pass the truth of these scans (on the scans' clock, in seconds)",
                    tp.display(),
                    odocal_core::REFERENCE_MAX_GAP_S * 1e3
                );
            }
            Some((tp, e))
        }
        None => None,
    };
    // Most confident poses far from the truth: the truth of other scans, or a map of another
    // room; either way these poses are no ground truth.
    let n_ok = count(Status::Ok);
    let refused = against.as_ref().and_then(|(tp, e)| {
        (n_ok > 0 && e.n_wrong_ok * 2 > n_ok).then(|| {
            // Positions that agree with headings that do not: the truth's theta, not the poses.
            if e.n_accuracy > 0 && e.position_rms_m <= odocal_lrf::CORRECT_POS_M {
                return format!(
                    "{} of {} confident poses are wrong against {} in heading only (position RMS {:.1} mm, heading RMS {:.1}°), so nothing was written: is its theta in radians (not degrees), counter-clockwise, and the heading of the scanner rather than of the robot it rides on?",
                    e.n_wrong_ok,
                    n_ok,
                    tp.display(),
                    e.position_rms_m * 1e3,
                    e.heading_rms_rad.to_degrees()
                );
            }
            format!(
                "{} of {} confident poses are wrong against {} (position RMS {:.1} mm), so nothing was written:{} is it the truth of these scans, and {} the map of this room?",
                e.n_wrong_ok,
                n_ok,
                tp.display(),
                e.position_rms_m * 1e3,
                odocal_lrf::truth_unit_hint(e.position_rms_m),
                a.map.display()
            )
        })
    });
    if refused.is_none() {
        // Both files are built before either is written.
        let trajectory = match &a.trajectory {
            Some(p) => Some((p, log.to_trajectory()?.to_csv())),
            None => None,
        };
        write_atomic(&a.out, log.to_csv().as_bytes())?;
        if let Some((p, csv)) = trajectory {
            write_atomic(p, csv.as_bytes())?;
        }
        commit()?;
    }
    let n = n_judged.max(1);
    let n_det_total: usize = log.rows.iter().map(|r| r.n_detections).sum();
    say!(
        "lrf localize: {} scans ({} mode): {} ok, {} ambiguous, {} lost{}; {:.1} detections/scan; {:.1} µs/scan; {}",
        log.rows.len(),
        if a.global_only { "global" } else { "tracking" },
        n_ok,
        count(Status::Ambiguous),
        count(Status::Lost),
        if n_repeated > 0 {
            format!(", {n_repeated} repeated")
        } else {
            String::new()
        },
        n_det_total as f64 / n as f64,
        elapsed.as_secs_f64() * 1e6 / n as f64,
        match (&refused, &a.trajectory) {
            (Some(_), _) => "nothing written".to_string(),
            (None, None) => format!("wrote {}", a.out.display()),
            (None, Some(t)) => format!("wrote {} and {}", a.out.display(), t.display()),
        }
    );
    // The first scan of a track carries its skew in its σ alone: one pose in many needs no word.
    if let Some(w) = skewed
        .as_ref()
        .filter(|w| w.n_widened > 0 && (a.global_only || w.n_widened * 10 > n_ok))
    {
        warn_skewed(w, a.global_only);
    }
    if let Some(w) = skewed.as_ref().filter(|w| w.n_motion_unknown > 0) {
        tell!(
            "warning: {} of {n_ok} poses could not be de-skewed and have no pose beside them to tell how far the sensor moved during their sweeps (a single scan, or one alone among lost scans): if the sensor moved, each is off by up to half its motion over a sweep, which its σ leaves out; localise it among the scans around it, or, if the scanner takes all beams at once or stood still, give --sweep-s 0",
            w.n_motion_unknown
        );
    }
    if n_repeated > 0 {
        tell!(
            "warning: {} the previous scan's ranges and intensities beam for beam (a driver republishing its last scan under a new time: range noise never repeats over a whole scan); {} not localised (status lost, mode repeated)",
            if n_repeated == 1 {
                "1 scan repeats".to_string()
            } else {
                format!("{n_repeated} scans repeat")
            },
            if n_repeated == 1 { "it was" } else { "they were" }
        );
    }
    if n_unsupported > 0 {
        tell!(
            "warning: {n_unsupported} {} no pose of the {} scans either side to agree with, among scans without one: a lone pose among lost scans (a robot driven out of the mapped area, or scans of another room) is more likely a coincidence than the scanner's place, so {} left out (status lost, mode unsupported)",
            if n_unsupported == 1 { "ok pose had" } else { "ok poses had" },
            odocal_lrf::SUPPORT_ROWS,
            if n_unsupported == 1 { "it was" } else { "they were" }
        );
    }
    if count(Status::Lost) * 2 > n_judged {
        tell!(
            "warning: {} of {} found no pose: {}",
            count(Status::Lost),
            scans_judged,
            noise_hint().unwrap_or_else(why_lost)
        );
    }
    // A quarter of the scans or more without a pose they could tell from another: the
    // written poses leave out much of the recording, for a reason the user can act on.
    if count(Status::Ambiguous) * 4 >= n_judged {
        tell!(
            "warning: {} of {} fit the map in several places and have no pose: {}",
            count(Status::Ambiguous),
            scans_judged,
            if layout_repeats(&loc.map, a.max_range_m) {
                format!(
                    "the landmarks of {} repeat themselves (a symmetric layout) where the scanner went; run `odocal lrf check-map {}` and add or move a landmark to break the symmetry",
                    a.map.display(),
                    a.map.display()
                )
            } else {
                why_lost()
            }
        );
    }
    if let Some((tp, e)) = &against {
        // An error over a few scans reads like the error of them all: say how few they are.
        if e.n_ok * 2 < n_ok {
            tell!(
                "warning: {} has the time of only {} of the {n_ok} ok scans ({} of all {} scans), so the figures against the truth are over those alone: are the scans and the truth timed on one clock, in seconds?",
                tp.display(),
                e.n_ok,
                e.n_scans,
                log.rows.len()
            );
        }
        // The bound beside each RMS: the mean over the same scans of each pose's Cramér–Rao
        // bound, from the matched detections' covariances and the map's.
        let bound = |rms: f64, crb: f64, unit: &str, scale: f64, digits: usize| {
            if e.n_bound == e.n_accuracy && crb > 0.0 {
                format!(
                    " (Cramér–Rao bound {:.digits$} {unit}, ratio {:.2})",
                    crb * scale,
                    rms / crb
                )
            } else {
                String::new()
            }
        };
        // An RMS over no scan would read as a perfect 0.0 mm: say there is none instead.
        let accuracy = if e.n_accuracy == 0 {
            "no error to report: no ok scan with >= 3 landmarks has a truth pose".to_string()
        } else {
            format!(
                "position RMS {:.1} mm{}, max {:.1} mm; heading RMS {:.3} deg{}; over {} ok scans with >= 3 landmarks",
                e.position_rms_m * 1e3,
                bound(e.position_rms_m, e.position_crb_m, "mm", 1e3, 1),
                e.position_max_m * 1e3,
                e.heading_rms_rad.to_degrees(),
                bound(e.heading_rms_rad, e.heading_crb_rad, "deg", 180.0 / std::f64::consts::PI, 3),
                e.n_accuracy
            )
        };
        say!(
            "vs truth: {accuracy}; confident wrong poses: {}{}; correct on {}/{} scans with >= 3 detected landmarks ({:.1} %){}",
            e.n_wrong_ok + e.n_beyond_sigma_ok,
            if e.n_beyond_sigma_ok > 0 {
                format!(
                    " ({} of them within 5 cm and 1° but more than {} of their σ off)",
                    e.n_beyond_sigma_ok,
                    odocal_lrf::BEYOND_SIGMAS
                )
            } else {
                String::new()
            },
            e.n_correct_eligible,
            e.n_eligible,
            100.0 * e.n_correct_eligible as f64 / e.n_eligible.max(1) as f64,
            if e.n_interpolated > 0 {
                format!(
                    "; the truth interpolated between rows ≤ {:.0} ms apart for {} of the {} scans judged",
                    odocal_core::REFERENCE_MAX_GAP_S * 1e3,
                    e.n_interpolated,
                    e.n_scans
                )
            } else {
                String::new()
            }
        );
        // Errors well beyond the bound the scanner's stated noise gives are errors the poses'
        // σ leave out (--sigma-range-m 0.0001 put them 5.9 times over, said of the map).
        let over = |rms: f64, crb: f64| if crb > 0.0 { rms / crb } else { 0.0 };
        let (pos, head) = (
            over(e.position_rms_m, e.position_crb_m),
            over(e.heading_rms_rad, e.heading_crb_rad),
        );
        if refused.is_none()
            && e.n_accuracy > 0
            && e.n_bound == e.n_accuracy
            && pos.max(head) > MAX_BOUND_RATIO
        {
            tell!(
                "warning: against {} the poses lie {pos:.1} times (position) and {head:.1} times (heading) their Cramér–Rao bound from the truth, so their σ are too small for these scans: is --sigma-range-m {} the scanner's range noise (1σ of its data sheet), and the beams' sweep time (--sweep-s) its own? A map off by more than its position_sigma_m does the same",
                tp.display(),
                a.sigma_range_m,
            );
        }
    }
    if let Some(why) = refused {
        anyhow::bail!(why);
    }
    Ok(())
}

/// The error-to-bound ratio against a truth beyond which the poses' σ are called too small:
/// over the test seeds an honest σ gives 0.6–1.4.
const MAX_BOUND_RATIO: f64 = 2.0;
