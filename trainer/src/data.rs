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
    check_dataset(&ds)?;
    Ok((ds, sha256_hex(bytes)))
}

/// Checks a dataset built in memory as [`Dataset::parse`] checks a file, and that it has
/// samples to train on.
pub fn check_dataset(ds: &Dataset) -> Result<(), TrainError> {
    ds.check().map_err(TrainError::Dataset)?;
    if ds.samples.is_empty() {
        return Err(TrainError::Dataset(
            "no samples (all runs rejected?); nothing to train on".into(),
        ));
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
