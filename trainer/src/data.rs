//! Loading and checking dataset.json for training.

use odocal_dataset::{Dataset, Sample};
use sha2::{Digest, Sha256};

use crate::error::TrainError;

/// Hex SHA-256 of a file's bytes (what `sha256sum` prints).
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

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

/// The fewest samples training accepts (one to hold out for early stopping, two to fit).
pub const MIN_SAMPLES: usize = 3;

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
            "the dataset has {} sample(s); a corrector needs at least {MIN_SAMPLES} runs to fit and check",
            ds.samples.len()
        )));
    }
    check_no_copies(&ds.samples)
}

/// Refuses samples that repeat another sample (the same run id, or the same inputs to the
/// last bit): copies would sit on both sides of a cross-validation fold and report the
/// training error as the error on unseen runs.
fn check_no_copies(samples: &[Sample]) -> Result<(), TrainError> {
    let mut seen_ids = std::collections::HashMap::new();
    let mut seen_inputs = std::collections::HashMap::new();
    let mut copies = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        let bits: Vec<u64> = s.inputs.iter().map(|v| v.to_bits()).collect();
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
