//! Loading and checking dataset.json for training.

pub use odocal_core::sha256_hex;
use odocal_dataset::{Dataset, Sample, N_INPUTS};

use crate::error::TrainError;

/// Parses dataset.json bytes with the dataset crate's one reader ([`Dataset::parse`]) and
/// checks that there is something to train on; returns the dataset and the SHA-256 of the
/// bytes (which model.json records).
pub fn parse_dataset(bytes: &[u8], name: &str) -> Result<(Dataset, String), TrainError> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| TrainError::Dataset(format!("{name}: not UTF-8 text ({e})")))?;
    let ds = Dataset::parse(text, name).map_err(|e| TrainError::Dataset(e.to_string()))?;
    check_dataset(&ds).map_err(|e| match e {
        TrainError::Dataset(m) => TrainError::Dataset(format!("{name}: {m}")),
        TrainError::TooFewSamples(m) => TrainError::TooFewSamples(format!("{name}: {m}")),
        other => other,
    })?;
    Ok((ds, sha256_hex(bytes)))
}

/// The fewest samples training accepts (three to fit, one held out for early stopping), so
/// that a dataset let through here is not refused by training itself.
pub const MIN_SAMPLES: usize = 4;

/// Checks a dataset built in memory as [`Dataset::parse`] checks a file, and that it has
/// samples to train on.
pub fn check_dataset(ds: &Dataset) -> Result<(), TrainError> {
    ds.check().map_err(TrainError::Dataset)?;
    if ds.samples.is_empty() {
        return Err(TrainError::Dataset(
            "no samples (all runs rejected?); nothing to train on".into(),
        ));
    }
    if ds.samples.len() < MIN_SAMPLES {
        return Err(TrainError::TooFewSamples(format!(
            "the dataset has {} sample(s); a corrector needs at least {MIN_SAMPLES} runs (3 to fit, 1 held out to check; a useful one, tens): build the dataset from more runs",
            ds.samples.len()
        )));
    }
    if !ds.is_windows() {
        check_run_times(&ds.samples)?;
    }
    check_no_copies(&ds.samples)?;
    check_targets_move(&ds.samples)
}

/// Refuses straight-run samples whose run times (inputs 16 and 17, t_b and t_e in the
/// feature rule) run backwards or are no clock readings: the intermediate positions are
/// placed at t_b + i/9 (t_e - t_b), so a swap reverses the run in time.
fn check_run_times(samples: &[Sample]) -> Result<(), TrainError> {
    for (i, s) in samples.iter().enumerate() {
        let (t_b, t_e) = (s.inputs[N_INPUTS - 2], s.inputs[N_INPUTS - 1]);
        if !(t_b >= 0.0 && t_e > t_b) {
            return Err(TrainError::Dataset(format!(
                "sample {i} (run '{}'): its run starts at t_b = {t_b} s and ends at t_e = {t_e} s (inputs 16 and 17); the feature rule needs 0 <= t_b < t_e (robot clock seconds): are they swapped? rebuild the dataset with `odocal dataset`",
                s.run_id
            )));
        }
    }
    Ok(())
}

/// The camera's motion against raw odometry's (sums of end distances from the start over the
/// samples) below which the targets carry no motion: a frozen or lost camera track.
const NO_MOTION_RATIO: f64 = 0.05;
/// The range of that ratio for targets and odometry in the same unit: odometry is off by a
/// few percent to a few tens of percent (11 % on tours, 3 % on straight runs), never by 2x.
const SAME_UNIT_RATIO: std::ops::RangeInclusive<f64> = 0.5..=2.0;

/// Refuses targets that do not move with the odometry: all (0, 0) from a camera track that
/// froze trains a "corrector" to 0 % error that stops every robot, and targets in
/// millimetres against odometry in metres leave no fit that converges.
fn check_targets_move(samples: &[Sample]) -> Result<(), TrainError> {
    let dist = |v: &[f64; 2]| v[0].hypot(v[1]);
    let n = samples.len().max(1) as f64;
    let camera = samples.iter().map(|s| dist(&s.target_m)).sum::<f64>() / n;
    let odometry = samples.iter().map(|s| dist(&s.raw_end_m)).sum::<f64>() / n;
    if odometry <= 0.0 {
        return Ok(());
    }
    let ratio = camera / odometry;
    if ratio < NO_MOTION_RATIO {
        return Err(TrainError::Dataset(format!(
            "the targets carry no motion: the camera's end points lie {:.1} mm from their starts on average, raw odometry's {odometry:.3} m; a frozen or lost camera track? check the trajectories (`odocal track` reports the frames it lost) and rebuild the dataset",
            1e3 * camera
        )));
    }
    if !SAME_UNIT_RATIO.contains(&ratio) {
        let unit = if (500.0..=2000.0).contains(&ratio) {
            "are the trajectories in millimetres? "
        } else if (50.0..=200.0).contains(&ratio) {
            "are the trajectories in centimetres? "
        } else {
            ""
        };
        return Err(TrainError::Dataset(format!(
            "the camera's end points lie {} times as far from their starts as raw odometry's ({camera:.3} m against {odometry:.3} m on average): {unit}odocal expects trajectories in metres and the robot's true wheel diameter and encoder counts; fix them and rebuild the dataset",
            if ratio < 10.0 {
                format!("{ratio:.3}")
            } else {
                format!("{ratio:.0}")
            }
        )));
    }
    Ok(())
}

/// Refuses samples that repeat another sample (the same run id, or the same inputs and
/// target to the last bit): copies would sit on both sides of a cross-validation fold and
/// report the training error as the error on unseen runs. Inputs alone are no copy: two
/// windows of one speed on straight legs of different recordings count the same ticks,
/// while the camera saw each end somewhere else.
fn check_no_copies(samples: &[Sample]) -> Result<(), TrainError> {
    let mut seen_ids = std::collections::HashMap::new();
    let mut seen_inputs = std::collections::HashMap::new();
    let mut copies = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        let bits: Vec<u64> = s
            .inputs
            .iter()
            .chain(&s.target_m)
            .chain([&s.target_theta_rad])
            .map(|v| v.to_bits())
            .collect();
        let by_id = seen_ids.insert(s.run_id.clone(), i);
        let by_inputs = seen_inputs.insert(bits, i);
        if let Some(j) = by_id.or(by_inputs) {
            copies.push(format!(
                "sample {i} (run '{}') repeats sample {j}",
                s.run_id
            ));
        }
    }
    if copies.is_empty() {
        return Ok(());
    }
    Err(TrainError::Dataset(format!(
        "{} of {} samples are copies of others ({}{}); remove the copies: cross-validation would score them on themselves",
        copies.len(),
        samples.len(),
        copies[..copies.len().min(3)].join(", "),
        if copies.len() > 3 { ", ..." } else { "" }
    )))
}

/// The odometry polyline of a sample: start (0,0), the eight intermediate positions and the raw end.
pub fn odometry_polyline(s: &Sample) -> [[f64; 2]; 10] {
    let mut p = [[0.0; 2]; 10];
    for i in 0..8 {
        p[i + 1] = [s.inputs[2 * i], s.inputs[2 * i + 1]];
    }
    p[9] = s.raw_end_m;
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> Vec<Sample> {
        let text = include_str!("../../tests/data/parsers/dataset.json");
        let ds = Dataset::parse(text, "dataset.json").expect("the test dataset parses");
        ds.samples
    }

    /// Straight legs at one speed in two recordings log the same ticks; a path model's
    /// windows of a dozen tours held six such pairs, and the whole training was refused.
    #[test]
    fn equal_inputs_with_their_own_targets_are_no_copies() {
        let one = samples().remove(0);
        let mut other = one.clone();
        other.run_id.push_str(".elsewhere");
        other.target_m[1] += 0.01;
        assert!(check_no_copies(&[one.clone(), other]).is_ok());
        let mut copy = one.clone();
        copy.run_id.push_str(".copy");
        let Err(TrainError::Dataset(e)) = check_no_copies(&[one, copy]) else {
            panic!("a copy under another name passed")
        };
        assert!(e.contains("1 of 2 samples are copies"), "{e}");
    }
}
