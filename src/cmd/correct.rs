//! `odocal correct`: applies a trained corrector to a raw 200 ms odometry log.

use std::path::PathBuf;

use odocal_dataset::{OdometryLog, RobotParams};
use odocal_trainer::{ModelFile, PathModelFile, PATH_MODEL_FORMAT};

use crate::output::{check_output_file, commit, write_atomic};

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// The trained model (model.json from `odocal train`): a straight-run model corrects the
    /// end point of one run; a path model (trained on windows) corrects a log of any path.
    #[arg(long)]
    pub model: PathBuf,
    /// The raw odometry log (for a straight-run model: of one run) (`t,left_ticks,right_ticks`: cumulative encoder counts; or `t,v_left,v_right`: wheel speeds in m/s; t in seconds).
    pub log: PathBuf,
    /// Robot parameters of the log (robot.json, "format": "odocal.robot/1"); default: the model's robot.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Where to write the corrected track (CSV); without it only the end point is printed.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Correct a log outside the model's training domain anyway (longer or shorter runs,
    /// reversing, inputs beyond the trained range); the result is flagged as a guess.
    #[arg(long)]
    pub allow_extrapolation: bool,
}

/// The robot (`--robot`, else the model's) and the log to correct.
fn robot_and_log(
    args: &Args,
    model_robot: RobotParams,
) -> anyhow::Result<(RobotParams, OdometryLog)> {
    let robot = match &args.robot {
        Some(p) => RobotParams::read(p)?,
        None => model_robot,
    };
    let log = OdometryLog::read_csv(&args.log)?;
    if let Some(n) = log.count_note() {
        tell!("note: {}: {n}", args.log.display());
    }
    let (log, mended) = odocal_dataset::glitch::mend_garbled_readings(&log, &robot);
    for m in mended {
        tell!("warning: {}: {m}", args.log.display());
    }
    Ok((robot, log))
}

/// The error of correcting the log: one that names the log (its gaps, glitches, period,
/// motion) is the log's, and is not put on the model file; the rest (a model of another
/// robot, a damaged model) is the model's.
fn blame(e: odocal_trainer::TrainError, args: &Args) -> anyhow::Error {
    let log = args.log.display().to_string();
    let text = match &e {
        odocal_trainer::TrainError::Dataset(m) | odocal_trainer::TrainError::Model(m) => m,
        _ => return anyhow::Error::new(e).context(args.model.display().to_string()),
    };
    if text.starts_with(&format!("{log}:")) {
        anyhow::anyhow!("{text}")
    } else {
        anyhow::Error::new(e).context(args.model.display().to_string())
    }
}

/// Warns of each way the log lies outside the training domain (a flagged guess, not an error
/// with `--allow-extrapolation`).
fn warn_outside_domain(outside_domain: &[String]) {
    for why in outside_domain {
        tell!("warning: EXTRAPOLATED, outside the training domain: {why}");
    }
}

/// Writes the corrected track to `--out`, when given.
fn write_track(args: &Args, csv: String) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        write_atomic(out, csv.as_bytes())?;
        commit()?;
        say!("wrote {}", out.display());
    }
    Ok(())
}

/// Corrects a log of any path with a path model: the whole corrected trajectory.
fn correct_path(args: &Args) -> anyhow::Result<()> {
    let model = PathModelFile::read(&args.model)?;
    if let Some(w) = model.unrecorded_directions(&args.model.display().to_string()) {
        tell!("warning: {w}");
    }
    let (robot, log) = robot_and_log(args, model.robot)?;
    let run = model
        .correct_log(
            &log,
            &robot,
            &args.log.display().to_string(),
            args.allow_extrapolation,
        )
        .map_err(|e| blame(e, args))?;
    warn_outside_domain(&run.outside_domain);
    let (raw, corrected) = run.ends();
    check_reach(
        corrected.x_m.hypot(corrected.y_m),
        run.path_length_m,
        &args.model,
    )?;
    say!(
        "raw odometry end: x {:.4} m, y {:.4} m, heading {:.2} deg; corrected end: x {:.4} m, y {:.4} m, heading {:.2} deg (start frame; correction {:.2} cm and {:+.2} deg of turning over {:.3} m of wheel travel)",
        raw.x_m,
        raw.y_m,
        odocal_core::wrap_angle(raw.theta_rad).to_degrees(),
        corrected.x_m,
        corrected.y_m,
        odocal_core::wrap_angle(corrected.theta_rad).to_degrees(),
        100.0 * (corrected.x_m - raw.x_m).hypot(corrected.y_m - raw.y_m),
        // The headings are shown within ±180°; the turning they differ by is not.
        (corrected.theta_rad - raw.theta_rad).to_degrees(),
        run.path_length_m
    );
    write_track(args, run.to_csv())
}

/// Refuses a corrected end farther from the start than the wheels could have carried the
/// robot (their travel, half again for slip and a wheel's error, and 5 cm): no correction
/// of a real robot does that, only a damaged or edited model.
fn check_reach(end_m: f64, path_length_m: f64, model: &std::path::Path) -> anyhow::Result<()> {
    let reach_m = 1.5 * path_length_m + 0.05;
    if end_m.is_finite() && end_m <= reach_m {
        return Ok(());
    }
    anyhow::bail!(
        "{}: the model puts the corrected end {end_m:.3} m from the start after {path_length_m:.3} m of wheel travel, farther than any robot gets on it ({reach_m:.3} m at most): its weights are damaged or edited; train it again",
        model.display()
    )
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        check_output_file(out, "--out")?;
    }
    let kind = odocal_core::read_text(&args.model)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v.get("format").and_then(|f| f.as_str()).map(str::to_string));
    if kind.as_deref() == Some(PATH_MODEL_FORMAT) {
        return correct_path(&args);
    }
    let model = ModelFile::read(&args.model)?;
    let name = args.model.display().to_string();
    for w in [
        model.untrained_warning(&name),
        model.no_domain_warning(&name),
    ]
    .into_iter()
    .flatten()
    {
        tell!("warning: {w}");
    }
    let (robot, log) = robot_and_log(&args, model.robot)?;
    let run = model
        .correct_log(
            &log,
            &robot,
            &args.log.display().to_string(),
            args.allow_extrapolation,
        )
        .map_err(|e| blame(e, &args))?;
    let (raw, corrected) = (run.raw_end_m, run.corrected_end_m);
    warn_outside_domain(&run.outside_domain);
    check_reach(
        corrected[0].hypot(corrected[1]),
        run.path_length_m,
        &args.model,
    )?;
    say!(
        "raw odometry end: x {:.4} m, y {:.4} m; corrected end: x {:.4} m, y {:.4} m (start frame; correction {:.2} cm over {:.3} m of odometry)",
        raw[0],
        raw[1],
        corrected[0],
        corrected[1],
        100.0 * (corrected[0] - raw[0]).hypot(corrected[1] - raw[1]),
        run.path_length_m
    );
    // The figure the correction is only as good as, said beside it.
    match model.held_out_error(&name) {
        Ok((error, measured)) => say!(
            "the model's end-point error on runs it was not fitted to: {:.2} % of the path ({measured}), about {:.1} cm over this run's; raw odometry's on its training runs {:.2} %",
            100.0 * error,
            100.0 * error * run.path_length_m,
            100.0 * model.metrics.raw_odometry.rel_error
        ),
        Err(w) => tell!("warning: {w}"),
    }
    write_track(&args, run.to_csv())
}
