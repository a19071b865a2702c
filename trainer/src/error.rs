//! Errors of the trainer.

use thiserror::Error;

/// Everything that can go wrong while loading data, training or applying a model.
#[derive(Debug, Error)]
pub enum TrainError {
    /// The dataset is unusable (empty, wrong format, wrong rule, NaN, wrong length...).
    #[error("dataset: {0}")]
    Dataset(String),
    /// A setting is outside its sensible range.
    #[error("settings: {0}")]
    Settings(String),
    /// Too few samples for the requested folds / validation split.
    #[error("too few samples: {0}")]
    TooFewSamples(String),
    /// A model file is unusable or does not fit the data it is applied to.
    #[error("model: {0}")]
    Model(String),
    /// A numerical failure of a fit.
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// A file could not be read or is not what it should be (names the file and position).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// JSON (de)serialisation failed.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}

impl TrainError {
    /// This error as a [`TrainError::Model`] of the model file `name` (a model's own error
    /// keeps its message, without a second "model: ").
    pub(crate) fn in_model_file(self, name: &str) -> Self {
        match self {
            Self::Model(m) => Self::Model(format!("{name}: {m}")),
            other => Self::Model(format!("{name}: {other}")),
        }
    }
}
