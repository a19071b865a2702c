//! Loading and checking dataset.json for training.

use odocal_dataset::{Dataset, Sample, DATASET_FORMAT, FEATURE_RULE, N_INPUTS};
use sha2::{Digest, Sha256};

use crate::error::TrainError;

/// Hex SHA-256 of a file's bytes (what `sha256sum` prints).
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// Parses and checks dataset.json bytes; returns the dataset and the SHA-256 of the bytes.
pub fn parse_dataset(bytes: &[u8]) -> Result<(Dataset, String), TrainError> {
    let value: serde_json::Value = serde_json::from_slice(bytes)
        .map_err(|e| TrainError::Dataset(format!("not valid JSON ({e})")))?;
    match value.get("format").and_then(|f| f.as_str()) {
        Some(DATASET_FORMAT) => {}
        Some(other) => {
            return Err(TrainError::Dataset(format!(
                "format is '{other}', expected '{DATASET_FORMAT}' (is this a dataset built by `odocal dataset`?)"
            )))
        }
        None => {
            return Err(TrainError::Dataset(format!(
                "no \"format\" field; expected '{DATASET_FORMAT}'"
            )))
        }
    }
    let ds: Dataset = serde_json::from_value(value)
        .map_err(|e| TrainError::Dataset(format!("does not match {DATASET_FORMAT} ({e})")))?;
    check_dataset(&ds)?;
    Ok((ds, sha256_hex(bytes)))
}

/// Checks that a dataset can be trained on: known rule, non-empty, 18 finite inputs per sample.
pub fn check_dataset(ds: &Dataset) -> Result<(), TrainError> {
    if ds.feature_rule != FEATURE_RULE {
        return Err(TrainError::Dataset(format!(
            "feature rule '{}' is not the rule this build uses ('{}'); rebuild the dataset",
            ds.feature_rule, FEATURE_RULE
        )));
    }
    if ds.samples.is_empty() {
        return Err(TrainError::Dataset(
            "no samples (all runs rejected?); nothing to train on".into(),
        ));
    }
    let r = &ds.robot;
    for (name, v) in [
        ("wheel_diameter_m", r.wheel_diameter_m),
        ("ticks_per_rev", r.ticks_per_rev),
        ("wheel_base_m", r.wheel_base_m),
        ("period_s", r.period_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(TrainError::Dataset(format!(
                "robot.{name} = {v} must be > 0"
            )));
        }
    }
    for (i, s) in ds.samples.iter().enumerate() {
        check_sample(i, s)?;
    }
    Ok(())
}

fn check_sample(i: usize, s: &Sample) -> Result<(), TrainError> {
    let at = format!("sample {i} (run '{}')", s.run_id);
    if s.inputs.len() != N_INPUTS {
        return Err(TrainError::Dataset(format!(
            "{at}: {} inputs, expected {N_INPUTS}",
            s.inputs.len()
        )));
    }
    if let Some(c) = s.inputs.iter().position(|v| !v.is_finite()) {
        return Err(TrainError::Dataset(format!(
            "{at}: input {c} is not a finite number"
        )));
    }
    if s.target_m
        .iter()
        .chain(s.raw_end_m.iter())
        .any(|v| !v.is_finite())
    {
        return Err(TrainError::Dataset(format!(
            "{at}: target or raw end point is not finite"
        )));
    }
    if !(s.path_length_m.is_finite() && s.path_length_m > 0.0) {
        return Err(TrainError::Dataset(format!(
            "{at}: path length {} must be > 0",
            s.path_length_m
        )));
    }
    if !s.speed_mps.is_finite() {
        return Err(TrainError::Dataset(format!("{at}: speed is not finite")));
    }
    Ok(())
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
