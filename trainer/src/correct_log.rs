//! Applying a trained model to a raw log: the end point corrected, and the whole track
//! carried along by the similarity transform (about the start) that takes the raw end point
//! to the corrected one, the same Helmert fit odocal uses for alignment and laser positioning.

use std::fmt::Write as _;

use nalgebra::Point2;
use odocal_core::{fit_helmert, Pose2};
use odocal_dataset::{features_from_log, OdometryLog, RobotParams, WheelGeometry, FEATURE_RULE};

use crate::{ModelFile, TrainError};

/// A log corrected by a model.
#[derive(Debug, Clone)]
pub struct CorrectedRun {
    /// Dead-reckoned end point of the raw log, start frame, metres.
    pub raw_end_m: [f64; 2],
    /// The model's corrected end point, start frame, metres.
    pub corrected_end_m: [f64; 2],
    /// Odometry's path length, metres.
    pub path_length_m: f64,
    /// Per logged step: time (s), the raw pose and the corrected position (start frame).
    pub track: Vec<(f64, Pose2, [f64; 2])>,
    /// Why the log lies outside the model's training domain (empty when inside).
    pub outside_domain: Vec<String>,
}

impl ModelFile {
    /// Corrects a raw log of `robot` (`name` is the log file, for messages): checks that the
    /// model fits the robot and that the log's period is the robot's, builds the features with
    /// the dataset's rule, and corrects the end point and the track. A log outside the
    /// model's training domain is refused unless `allow_extrapolation`, when the reasons are
    /// returned in [`CorrectedRun::outside_domain`] for the caller to flag.
    pub fn correct_log(
        &self,
        log: &OdometryLog,
        robot: &RobotParams,
        name: &str,
        allow_extrapolation: bool,
    ) -> Result<CorrectedRun, TrainError> {
        self.check_compatible(FEATURE_RULE, robot)?;
        crate::log_steps::check_log_steps(log, robot, name)?;
        let f = features_from_log(log, robot)
            .map_err(|e| TrainError::Dataset(format!("{name}: {e}")))?;
        let nominal = WheelGeometry::nominal(robot);
        let path_length_m = f.odometry.travel_m(&nominal);
        let outside_domain = self
            .domain
            .as_ref()
            .map(|d| d.outside(&f.inputs, f.raw_end_m))
            .unwrap_or_default();
        if !outside_domain.is_empty() && !allow_extrapolation {
            return Err(TrainError::Model(format!(
                "{name}: outside what the model was trained on: {}; a correction there would be a guess (pass --allow-extrapolation to get it anyway, flagged)",
                outside_domain.join("; ")
            )));
        }
        let corrected = self.correct(&f.inputs).map_err(|e| e.in_model_file(name))?;
        let raw = f.raw_end_m;
        // The start stays, the raw end goes to the corrected end: exact at both, a rotation
        // and scaling in between. A run that does not move keeps its raw track.
        let fit = fit_helmert(
            &[Point2::origin(), Point2::new(raw[0], raw[1])],
            &[Point2::origin(), Point2::new(corrected[0], corrected[1])],
        )
        .ok();
        // The start is fixed, so only the fit's rotation and scale are applied (its
        // translation is zero up to rounding).
        let (a, b) = fit.map_or((1.0, 0.0), |h| {
            let (sin, cos) = h.pose.theta_rad.sin_cos();
            (h.scale * cos, h.scale * sin)
        });
        let poses = f.odometry.poses(&nominal);
        let track = f
            .odometry
            .t_s
            .iter()
            .zip(&poses)
            .map(|(&t, p)| (t, *p, [a * p.x_m - b * p.y_m, b * p.x_m + a * p.y_m]))
            .collect();
        Ok(CorrectedRun {
            raw_end_m: raw,
            corrected_end_m: corrected,
            path_length_m,
            track,
            outside_domain,
        })
    }
}

impl CorrectedRun {
    /// The corrected track as CSV,
    /// `t,x_raw,y_raw,theta_raw,x_corrected,y_corrected,extrapolated` (`extrapolated` 1 on
    /// every row when the log lies outside the training domain: the file says its correction
    /// is a guess, not only the terminal that printed the warning).
    pub fn to_csv(&self) -> String {
        let mut csv =
            String::from("t,x_raw,y_raw,theta_raw,x_corrected,y_corrected,extrapolated\n");
        let flag = u8::from(!self.outside_domain.is_empty());
        for (t, p, c) in &self.track {
            let _ = writeln!(
                csv,
                "{t:.3},{:.6},{:.6},{:.6},{:.6},{:.6},{flag}",
                p.x_m, p.y_m, p.theta_rad, c[0], c[1]
            );
        }
        csv
    }
}
