//! One module per subcommand; each owns its arguments and its `run`.

pub mod arena;
pub mod board;
pub mod calibrate;
pub mod correct;
pub mod dataset;
pub mod evaluate;
pub mod lrf;
pub mod report;
pub mod synth_arena;
pub mod synth_calib;
pub mod synth_experiment;
pub mod synth_lrf;
pub mod synth_track;
pub mod tag;
pub mod track;
pub mod track_arena;
pub mod train;
