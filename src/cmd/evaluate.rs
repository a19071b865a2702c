//! `odocal evaluate`: judges a path model on held-out recordings (squares or any path) against
//! raw odometry, Borenstein's UMBMark calibration, the kinematic fit and, for synthetic
//! experiments, the oracle with the true kinematics.

use std::path::PathBuf;

use anyhow::{bail, Context};
use odocal_dataset::{Manifest, OracleFile, RobotParams, WheelGeometry};
use odocal_trainer::evaluate::{evaluate_paths, PathRecording, Reckoner};
use odocal_trainer::umbmark::{SquareError, Umbmark};
use odocal_trainer::PathModelFile;

use crate::output::{check_output_file, check_output_not_input, commit, write_json};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Manifest of the held-out recordings (each starts and ends at rest, seen by the camera).
    pub manifest: PathBuf,
    /// The path model (from `odocal train` on a window dataset).
    #[arg(long)]
    pub model: PathBuf,
    /// The recordings are UMBMark squares of this side, metres, driven both ways: adds
    /// Borenstein's E_max,syst per method.
    #[arg(long)]
    pub umbmark_m: Option<f64>,
    /// Manifest of other UMBMark squares (same side) to calibrate with Borenstein's E_d and
    /// E_b, the classic baseline; needs --umbmark-m.
    #[arg(long)]
    pub umbmark_calibration: Option<PathBuf>,
    /// Truth of a synthetic experiment (truth/oracle.json with the true kinematics): adds the
    /// oracle.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Robot parameters (robot.json); default: the model's robot.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Write the evaluation as JSON.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Evaluate recordings outside the model's training domain anyway (wheels faster than the
    /// training's, driven in directions it hardly saw); each is flagged, and the perceptron's
    /// figures with it.
    #[arg(long)]
    pub allow_extrapolation: bool,
}

/// The recordings of a manifest, with a note on each log whose encoder counts were unwrapped,
/// and a warning on each garbled reading read between its neighbours (as `dataset` does).
fn read_recordings(
    manifest: &std::path::Path,
    robot: &RobotParams,
) -> anyhow::Result<Vec<PathRecording>> {
    let mut recs = PathRecording::read_manifest(&Manifest::read(manifest)?)?;
    for r in &mut recs {
        if let Some(n) = r.log.count_note() {
            tell!("note: run \"{}\": {n}", r.id);
        }
        let (log, mended) = odocal_dataset::glitch::mend_garbled_readings(&r.log, robot);
        for m in mended {
            tell!("warning: run \"{}\" ({}): {m}", r.id, r.log_file.display());
        }
        r.log = log;
    }
    Ok(recs)
}

/// Refuses an `--umbmark-m` the squares' own wheel travel contradicts: a square of side L is
/// about 4 L of travel (the turns on the spot add a few centimetres), and UMBMark's E_d and
/// E_b scale with the side given.
fn check_square_side(
    runs: &[odocal_trainer::evaluate::RunResult],
    side_m: f64,
    manifest: &std::path::Path,
) -> anyhow::Result<()> {
    let mut travel: Vec<f64> = runs.iter().map(|r| r.path_length_m).collect();
    if travel.is_empty() {
        return Ok(());
    }
    travel.sort_by(f64::total_cmp);
    let measured = travel[travel.len() / 2] / 4.0;
    if !(0.8..=1.25).contains(&(side_m / measured)) {
        bail!(
            "--umbmark-m {side_m}: the squares of {} are {:.2} m a side by their wheel travel (median {:.2} m over {} recordings, a quarter of it); give the side the squares were driven at",
            manifest.display(),
            measured,
            4.0 * measured,
            runs.len()
        );
    }
    // Each square too: squares of another side averaged into the centres of gravity (4 of
    // 2 m among 6 of 4 m) gave E_max,syst with no word.
    let other: Vec<String> = runs
        .iter()
        .filter(|r| !(0.8..=1.25).contains(&(side_m / (r.path_length_m / 4.0))))
        .map(|r| format!("\"{}\" ({:.2} m)", r.id, r.path_length_m / 4.0))
        .collect();
    if !other.is_empty() {
        bail!(
            "--umbmark-m {side_m}: {} of the {} squares of {} are of another side by their wheel travel: {}; UMBMark compares squares of one side: leave them out of the manifest, or evaluate them on their own",
            other.len(),
            runs.len(),
            manifest.display(),
            other.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
        );
    }
    Ok(())
}

/// The share by which the camera's path and the wheels' travel (read with the model's
/// robot) may differ over all the recordings: turns on the spot move the wheels and not the
/// axle's midpoint, a few percent on tours.
const TRAVEL_SCALE_TOLERANCE: f64 = 0.15;

/// What to say when the camera's path over all the recordings and the wheels' travel read
/// with the model's robot differ beyond [`TRAVEL_SCALE_TOLERANCE`]: recordings of another
/// robot (wheels of 60 mm read as the model's 43 mm were judged, 28 % off, without a word),
/// whose errors the model's corrections do not describe.
fn travel_scale_warning(
    recs: &[odocal_trainer::evaluate::PathRecording],
    runs: &[odocal_trainer::evaluate::RunResult],
    robot: &odocal_dataset::RobotParams,
) -> Option<String> {
    let camera_m: f64 = recs
        .iter()
        .map(|r| {
            r.camera
                .rows
                .windows(2)
                .map(|w| (w[1].pose.position() - w[0].pose.position()).norm())
                .sum::<f64>()
        })
        .sum();
    let wheels_m: f64 = runs.iter().map(|r| r.path_length_m).sum();
    let scale = camera_m / wheels_m;
    (wheels_m > 0.0 && (scale - 1.0).abs() > TRAVEL_SCALE_TOLERANCE).then(|| {
        format!(
            "the camera followed {camera_m:.2} m of path where the wheels, read with the model's robot (wheel_diameter_m {}, ticks_per_rev {}), travelled {wheels_m:.2} m ({:+.0} %): recordings of another robot, or of these wheels changed? The model's corrections are for the robot it was trained on",
            robot.wheel_diameter_m,
            robot.ticks_per_rev,
            100.0 * (scale - 1.0)
        )
    })
}

/// Judges a held-out log against the model's training domain as `odocal correct` does: the
/// perceptron's figures on a log it was not trained for would be read as its accuracy.
/// Refused unless --allow-extrapolation, when it is flagged and the reasons returned; a log
/// with a gap is refused either way, as its steps' speeds would be misread, and the log is
/// named for it, not the model.
fn outside_domain(
    model: &PathModelFile,
    rec: &PathRecording,
    robot: &RobotParams,
    args: &Args,
) -> anyhow::Result<Vec<String>> {
    let name = format!("run \"{}\" of {}", rec.id, args.manifest.display());
    if let Some(why) = odocal_trainer::log_steps::log_step_problem(&rec.log, robot) {
        bail!("{} ({name}): {why}", rec.log_file.display());
    }
    let why = model
        .check_domain(&rec.log, robot, &name, args.allow_extrapolation)
        .with_context(|| format!("{}", args.model.display()))?;
    for w in &why {
        tell!("warning: EXTRAPOLATED, outside the training domain: {name}: {w}");
    }
    Ok(why)
}

/// A synthetic truth's ends this far (RMS) from the camera's are another experiment's.
const TRUTH_MISMATCH_M: f64 = odocal_dataset::TRUTH_MISMATCH_M;

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        check_output_file(out, "--out")?;
    }
    if let Some(side) = args.umbmark_m {
        if !(side.is_finite() && side > 0.0) {
            bail!("--umbmark-m {side}: the square's side must be a positive number of metres");
        }
    } else if args.umbmark_calibration.is_some() {
        bail!("--umbmark-calibration needs --umbmark-m (the squares' side, metres)");
    }
    // The logs and trajectories the manifests list are not arguments, so the check of
    // --out against the arguments cannot see them.
    if let Some(out) = &args.out {
        let manifests = std::iter::once(("the manifest", &args.manifest)).chain(
            args.umbmark_calibration
                .iter()
                .map(|c| ("the --umbmark-calibration manifest", c)),
        );
        for (which, path) in manifests {
            let inputs = Manifest::read(path)?.files();
            let whose = format!("listed in {which} {}", path.display());
            check_output_not_input(out, "--out", &inputs, &whose)?;
        }
    }
    let model = PathModelFile::read(&args.model)?;
    if let Some(w) = model.unrecorded_directions(&args.model.display().to_string()) {
        tell!("warning: {w}");
    }
    let robot = match &args.robot {
        Some(p) => RobotParams::read(p)?,
        None => model.robot,
    };
    model
        .check_robot(&robot, &args.manifest.display().to_string())
        .with_context(|| format!("{}", args.model.display()))?;
    let corrector = model.corrector()?;
    let truth_file = args.truth.as_deref().map(OracleFile::read).transpose()?;
    let truth = match (&args.truth, &truth_file) {
        (Some(p), Some(f)) => Some(f.kinematics.with_context(|| {
            format!("{}: holds no true kinematics (only `odocal synth experiment --paths tours|umbmark` writes them)", p.display())
        })?),
        _ => None,
    };
    let nominal = WheelGeometry::nominal(&robot);
    let mut methods: Vec<(String, Reckoner)> =
        vec![("raw odometry".into(), Reckoner::Geometry(nominal))];
    if let (Some(cal), Some(side)) = (&args.umbmark_calibration, args.umbmark_m) {
        let recs = read_recordings(cal, &robot)?;
        let ev = evaluate_paths(
            &recs,
            &robot,
            &[("raw".into(), Reckoner::Geometry(nominal))],
            true,
        )
        .with_context(|| format!("{}", cal.display()))?;
        check_square_side(&ev.runs, side, cal)?;
        if std::fs::canonicalize(cal).ok() == std::fs::canonicalize(&args.manifest).ok() {
            tell!(
                "warning: --umbmark-calibration {} is the manifest being evaluated: UMBMark's correction is then judged on the squares it was fitted to; calibrate on other squares",
                cal.display()
            );
        } else {
            // Another manifest listing the same logs (or copies) is the same squares.
            let shared = Manifest::read(cal)?.shared_files(&Manifest::read(&args.manifest)?);
            if let Some(first) = shared.first() {
                tell!(
                    "warning: --umbmark-calibration {} lists {} of the files the evaluated {} lists (the same file or the same bytes; {} is one): UMBMark's correction is then judged on the squares it was fitted to; calibrate on other squares",
                    cal.display(),
                    shared.len(),
                    args.manifest.display(),
                    first.display()
                );
            }
        }
        let errors: Vec<SquareError> = ev
            .runs
            .iter()
            .map(|r| SquareError {
                clockwise: r.clockwise == Some(true),
                error_m: r.errors_m[0],
            })
            .collect();
        let benchmark = Umbmark::of(&errors)?;
        if let Some(w) = benchmark.few_squares_warning("the UMBMark calibration (E_d, E_b)") {
            tell!("{w}");
        }
        let c = benchmark.correction(side, &robot);
        say!(
            "UMBMark calibration from {} squares: E_d = {:.5} (wheel diameter ratio right/left), E_b = {:.5} (wheel base factor)",
            errors.len(),
            c.e_d,
            c.e_b
        );
        methods.push((
            "UMBMark calibration (E_d, E_b)".into(),
            Reckoner::Geometry(c.geometry),
        ));
    }
    methods.push((
        "kinematic fit (windows)".into(),
        Reckoner::Geometry(model.kinematic_fit),
    ));
    methods.push((
        format!("perceptron 2-{}-3", corrector.hidden()),
        Reckoner::Corrector(&corrector),
    ));
    if let Some(k) = truth {
        methods.push(("oracle (true kinematics)".into(), Reckoner::Truth(k)));
    }
    let recs = read_recordings(&args.manifest, &robot)?;
    if let (Some(p), Some(f)) = (&args.truth, &truth_file) {
        match odocal_trainer::evaluate::truth_distance(&recs, f) {
            (Some(rms), _) if rms > TRUTH_MISMATCH_M => tell!(
                "warning: --truth: the recordings' camera trajectories end {:.0} mm RMS from the true ends in {}: is that the truth of the experiment {} lists? Its oracle row would judge another robot",
                1e3 * rms,
                p.display(),
                args.manifest.display()
            ),
            (_, missing) if missing > 0 => tell!(
                "warning: --truth: {} has no truth for {missing} of the {} recordings of {}: is that the truth of this experiment?",
                p.display(),
                recs.len(),
                args.manifest.display()
            ),
            _ => {}
        }
    }
    // Judged before any evaluation: a log with a gap or outside the domain is refused whole.
    let domains = recs
        .iter()
        .map(|rec| outside_domain(&model, rec, &robot, &args))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut ev = evaluate_paths(&recs, &robot, &methods, args.umbmark_m.is_some())
        .with_context(|| format!("{}", args.manifest.display()))?;
    // A recording the model was fitted on is no held-out recording: its figures are the
    // training's fit.
    let trained: Vec<(String, String)> = recs
        .iter()
        .filter_map(|r| {
            model
                .trained_on(&r.log)
                .map(|t| (r.id.clone(), t.to_string()))
        })
        .collect();
    if let Some((id, t)) = trained.first() {
        tell!(
            "warning: {} of the {} recordings of {} are recordings {} was trained on (run \"{id}\" holds training recording \"{t}\"'s steps): their figures are the training's fit, not held-out; evaluate on recordings the training did not see",
            trained.len(),
            recs.len(),
            args.manifest.display(),
            args.model.display()
        );
    }
    for (run, why) in ev.runs.iter_mut().zip(domains) {
        run.outside_domain = why;
    }
    if let Some(w) = travel_scale_warning(&recs, &ev.runs, &robot) {
        tell!("warning: {}: {w}", args.manifest.display());
    }
    let extrapolated = ev
        .runs
        .iter()
        .filter(|r| !r.outside_domain.is_empty())
        .count();
    if let Some(side) = args.umbmark_m {
        check_square_side(&ev.runs, side, &args.manifest)?;
    }
    if let Some(w) = ev
        .methods
        .first()
        .and_then(|m| m.umbmark.as_ref())
        .and_then(|u| u.few_squares_warning("every E_max,syst below"))
    {
        tell!("{w}");
    }
    let path_m: f64 = ev.runs.iter().map(|r| r.path_length_m).sum();
    say!(
        "{} {}, {path_m:.1} m of wheel travel; end-point error per metre driven (mean over recordings){}:",
        ev.runs.len(),
        if trained.is_empty() {
            "held-out recordings".to_string()
        } else {
            format!(
                "recordings ({} of them training recordings, not held out)",
                trained.len()
            )
        },
        if args.umbmark_m.is_some() {
            "; UMBMark E_max,syst = larger distance of the clockwise and counter-clockwise error centres"
        } else {
            ""
        }
    );
    for m in &ev.methods {
        match &m.umbmark {
            Some(u) => say!(
                "  {:<32} {:6.2} % of path   E_max,syst {:8.1} mm (cw {:.1} mm, ccw {:.1} mm; {}+{} squares)",
                m.name,
                100.0 * m.end_error_per_m,
                1e3 * u.e_max_syst_m,
                1e3 * u.r_cw_m,
                1e3 * u.r_ccw_m,
                u.runs[0],
                u.runs[1]
            ),
            None => say!("  {:<32} {:6.2} % of path", m.name, 100.0 * m.end_error_per_m),
        }
    }
    if extrapolated > 0 {
        say!(
            "  EXTRAPOLATED: {extrapolated} of {} recordings lie outside the perceptron's training domain (warnings above; outside_domain in --out): its figures include its guesses there",
            ev.runs.len()
        );
    }
    if let Some(out) = &args.out {
        write_json(out, &ev)?;
        commit()?;
        say!("wrote {}", out.display());
    }
    Ok(())
}
