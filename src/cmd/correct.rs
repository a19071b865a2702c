//! `odocal correct`: applies a trained corrector to a raw 200 ms odometry log.

use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use odocal_dataset::{
    features_from_log, OdometryLog, RobotParams, RunFeatures, WheelGeometry, FEATURE_RULE,
};
use odocal_trainer::ModelFile;

use crate::output::write_atomic;

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// The trained model (model.json from `odocal train`).
    #[arg(long)]
    pub model: PathBuf,
    /// The raw odometry log of one run (`t,left_ticks,right_ticks` or `t,v_left,v_right`).
    pub log: PathBuf,
    /// Robot parameters of the log (robot.json, "format": "odocal.robot/1"); default: the model's robot.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Where to write the corrected track (CSV); without it only the end point is printed.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The features of the log, built with the dataset crate's feature builder (the dataset's rule).
fn build_features(log: &OdometryLog, robot: &RobotParams) -> anyhow::Result<RunFeatures> {
    Ok(features_from_log(log, robot)?)
}

/// Median interval between log rows, seconds.
fn median_period_s(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = ModelFile::read(&args.model)?;
    let robot = match &args.robot {
        Some(p) => RobotParams::read(p)?,
        None => model.robot,
    };
    model
        .check_compatible(FEATURE_RULE, &robot)
        .with_context(|| format!("{}", args.model.display()))?;
    let log = OdometryLog::read_csv(&args.log)?;
    if let Some(p) = median_period_s(&log.t_s) {
        if (p - robot.period_s).abs() > 0.05 * robot.period_s {
            bail!(
                "{}: rows are {:.3} s apart, but the model's robot logs every {:.3} s; this log is of another robot or logger",
                args.log.display(),
                p,
                robot.period_s
            );
        }
    }
    let f = build_features(&log, &robot).with_context(|| format!("{}", args.log.display()))?;
    let corrected = model
        .correct(&f.inputs)
        .with_context(|| format!("{}", args.log.display()))?;
    let raw = f.raw_end_m;
    let len_m = f.odometry.travel_m(&WheelGeometry::nominal(&robot));
    println!(
        "raw odometry end: x {:.4} m, y {:.4} m; corrected end: x {:.4} m, y {:.4} m (start frame; correction {:.2} cm over {:.3} m of odometry)",
        raw[0],
        raw[1],
        corrected[0],
        corrected[1],
        100.0 * (corrected[0] - raw[0]).hypot(corrected[1] - raw[1]),
        len_m
    );
    if let Some(out) = &args.out {
        // The corrected track: the raw track rotated and scaled about the start so that its end
        // lands on the corrected end point (exact at the end, an interpolation in between).
        let poses = f.odometry.poses(&WheelGeometry::nominal(&robot));
        let r2 = raw[0] * raw[0] + raw[1] * raw[1];
        let (a, b) = if r2 > 1e-12 {
            (
                (corrected[0] * raw[0] + corrected[1] * raw[1]) / r2,
                (corrected[1] * raw[0] - corrected[0] * raw[1]) / r2,
            )
        } else {
            (1.0, 0.0)
        };
        let mut csv = String::from("t,x_raw,y_raw,theta_raw,x_corrected,y_corrected\n");
        for (t, p) in f.odometry.t_s.iter().zip(&poses) {
            let _ = writeln!(
                csv,
                "{t:.3},{:.6},{:.6},{:.6},{:.6},{:.6}",
                p.x_m,
                p.y_m,
                p.theta_rad,
                a * p.x_m - b * p.y_m,
                b * p.x_m + a * p.y_m
            );
        }
        write_atomic(out, csv.as_bytes())?;
        println!("wrote {}", out.display());
    }
    Ok(())
}
