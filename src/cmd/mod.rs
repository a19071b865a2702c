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

/// Refuses a count past what `synth` renders, before anything is allocated: four billion
/// frames asked for aborted on a 2 TB allocation; `what` says what the limit covers.
pub(crate) fn synth_count_at_most(
    n: usize,
    option: &str,
    max: usize,
    what: &str,
) -> anyhow::Result<()> {
    if n > max {
        anyhow::bail!("{option} {n}: synth renders at most {max} ({what}); ask for fewer");
    }
    Ok(())
}
