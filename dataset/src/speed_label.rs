//! Checking a manifest's commanded speed (`speed_mps`) against the speeds the camera saw. A
//! label in mm/s or cm/s, or another run's (rows of the manifest mixed up), would otherwise
//! be stored as the run's and spread its errors over the wrong speed in `train --sweep`. The
//! run's mean speed is no measure of its command: a short run's ramps keep it well below
//! (0.4 m at 0.7 m/s and 1 m/s² peaks at 0.63 m/s and averages 0.29 m/s), and such runs were
//! refused as mixed up while their labels were right.

use odocal_core::Trajectory;

use crate::align::camera_speed;

/// Mean speed over peak speed at or above which a run cruised at its peak. A run too short to
/// reach its command is all ramps, and the mean of a triangle of speed is half its peak; a
/// run holding its speed for most of its time has a mean near its peak (1.5 m at 0.7 m/s and
/// 1 m/s²: 0.76).
const CRUISE_FILL: f64 = 2.0 / 3.0;

/// Factor by which a command may lie off the peak of a run that cruised at it (either way).
const MAX_FACTOR: f64 = 2.0;

/// The camera's fastest speed over one log step of a run, either way, m/s
/// ([`camera_speed`] between the log rows' times `t_s` moved to the camera's clock by
/// `offset_s`), steps over a frame gap (longer than `max_gap_s`) left out.
pub fn camera_peak_speed_mps(
    camera: &Trajectory,
    t_s: &[f64],
    offset_s: f64,
    max_gap_s: f64,
) -> f64 {
    t_s.windows(2)
        .filter_map(|w| camera_speed(camera, w[0] + offset_s, w[1] + offset_s, max_gap_s))
        .map(f64::abs)
        .fold(0.0, f64::max)
}

/// Why the manifest's commanded speed `v_mps` cannot be that of a run the camera saw reach
/// `peak_mps` at most and average `mean_mps`, or `None` when it can. A robot does not reach
/// twice its command, so a command below half the peak is refused; one above twice the peak
/// only when the run cruised at its peak, or by a unit's factor: a run that never cruised
/// shows only that its command lies above its peak.
pub fn commanded_speed_mismatch(v_mps: f64, peak_mps: f64, mean_mps: f64) -> Option<String> {
    if peak_mps <= 0.0 {
        return None;
    }
    let ratio = v_mps / peak_mps;
    let cruised = mean_mps >= CRUISE_FILL * peak_mps;
    let unit = match ratio {
        r if (400.0..=2500.0).contains(&r) => Some("is it in mm/s?"),
        r if (40.0..=250.0).contains(&r) => Some("is it in cm/s?"),
        _ => None,
    };
    let too_high = ratio > MAX_FACTOR && (cruised || ratio >= 40.0);
    if !(ratio < 1.0 / MAX_FACTOR || too_high) {
        return None;
    }
    let held = if cruised {
        format!(" and held (averaging {mean_mps:.3} m/s)")
    } else {
        String::new()
    };
    Some(format!(
        "the manifest's speed_mps {v_mps} is {ratio:.3} times the {peak_mps:.3} m/s the camera saw the run reach{held}: {} It must be the run's commanded speed in m/s (or leave it out to use the odometry's)",
        unit.unwrap_or("is it another run's label (rows of the manifest mixed up)?")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_runs_below_their_command_pass_and_other_runs_labels_do_not() {
        // 0.4 m at 0.7 m/s and 1 m/s²: a triangle peaking at 0.63, averaging 0.29 (the
        // camera's figures of a synthetic run). Its mean is 0.41 of the command; it passes.
        assert_eq!(commanded_speed_mismatch(0.7, 0.61, 0.294), None);
        // 1.5 m runs: 0.7 m/s on a run that cruised at 0.2, and 0.2 on one at 0.7.
        let high = commanded_speed_mismatch(0.7, 0.205, 0.19).expect("0.7 on a 0.2 run");
        assert!(
            high.contains("is 3.415 times the 0.205 m/s the camera saw the run reach and held")
                && high.contains("rows of the manifest mixed up"),
            "{high}"
        );
        let low = commanded_speed_mismatch(0.2, 0.71, 0.53).expect("0.2 on a 0.7 run");
        assert!(low.contains("0.282 times"), "{low}");
        // A short run labelled with a slow run's speed: it went faster than twice that.
        assert!(commanded_speed_mismatch(0.2, 0.61, 0.294).is_some());
        // Units, whether the run cruised or not.
        for mean in [0.19, 0.1] {
            let mm = commanded_speed_mismatch(200.0, 0.2, mean).expect("mm/s");
            assert!(mm.contains("is it in mm/s?"), "{mm}");
            let cm = commanded_speed_mismatch(20.0, 0.2, mean).expect("cm/s");
            assert!(cm.contains("is it in cm/s?"), "{cm}");
        }
    }
}
