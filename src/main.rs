//! odocal: ceiling-camera ground truth and learned odometry correction for
//! small wheeled robots. This binary only parses arguments, shows progress and
//! reports; the work is done by the library crates.

use clap::{CommandFactory, FromArgMatches, Subcommand};

/// `say!` that carries on when standard output is closed (`odocal dataset … | head -1`):
/// the command's outputs are files committed after its summary is printed, and must not be
/// lost with a line nobody reads (a closed pipe would otherwise end the process there).
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($t)*) {
            $crate::output::stdout_failed(e);
        }
    }};
}

/// `tell!` that carries on when standard error is closed, as [`say!`]; long numbers are
/// written short ([`short_numbers`]: a warning quoting a tick count of 1e308 read as 309
/// digits).
macro_rules! tell {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "{}", $crate::short_numbers(&format!($($t)*)));
    }};
}

mod blas;
mod cmd;
mod output;

/// Ceiling-camera ground truth, odometry correction and laser positioning for small robots.
#[derive(clap::Parser)]
#[command(name = "odocal", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render synthetic inputs with known truth.
    #[command(subcommand)]
    Synth(SynthCommand),
    /// Calibrate a camera from checkerboard or ChArUco images (Zhang's method) and fix the floor plane.
    Calibrate(cmd::calibrate::Args),
    /// Tie several calibrated cameras into one floor frame with boards on the floor in their overlaps.
    Arena(cmd::arena::Args),
    /// Track the robot's AprilTag through a video into a floor trajectory.
    Track(cmd::track::Args),
    /// Build the training set from runs (videos or trajectories) and odometry logs.
    Dataset(cmd::dataset::Args),
    /// Train the odometry corrector, or sweep hidden sizes with cross-validation.
    Train(cmd::train::Args),
    /// Correct a raw 200 ms odometry log with a trained model.
    Correct(cmd::correct::Args),
    /// Judge a path model on held-out squares (UMBMark) or tours against its baselines.
    Evaluate(cmd::evaluate::Args),
    /// Laser positioning among reflective landmarks.
    #[command(subcommand)]
    Lrf(cmd::lrf::Command),
    /// Write one self-contained HTML report (inline SVG plots) from the stage outputs.
    Report(cmd::report::Args),
}

#[derive(Subcommand)]
enum SynthCommand {
    /// Checkerboard or ChArUco views (and floor views) from a known camera.
    Calib(cmd::synth_calib::Args),
    /// Compare a camera.json with the truth of `synth calib`.
    CheckCalib(cmd::synth_calib::CheckArgs),
    /// A ceiling video of a robot carrying an AprilTag, with the true trajectory.
    Track(cmd::synth_track::Args),
    /// The whole odometry experiment: runs, logs, videos and truth.
    Experiment(cmd::synth_experiment::Args),
    /// A 6 x 4 m arena under four cameras, shared floor boards and two robots, with truth.
    Arena(cmd::synth_arena::Args),
    /// A landmark map, a sensor trajectory and laser scans.
    Lrf(cmd::synth_lrf::Args),
}

/// A negative number after an option is its value: `--tag-size -1` reaches odocal's own
/// check of the value instead of clap's "unexpected argument '-1'".
fn negative_numbers_are_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if a.get_action().takes_values() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_numbers_are_values)
}

/// Exits on a command line clap could not parse: help and version as clap shows them, any
/// other error as one line with exit code 2, like every other error (clap's own takes three
/// to seven lines, with the usage).
fn usage_error(e: clap::Error) -> ! {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit()
    }
    tell!(
        "odocal: error: {}",
        one_line_usage_error(&e.render().to_string())
    );
    std::process::exit(2)
}

/// clap's error text as one line: its message and tips, without the usage and the pointer
/// to --help (said once at the end).
fn one_line_usage_error(text: &str) -> String {
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| {
            !(l.is_empty() || l.starts_with("Usage:") || l.starts_with("For more information"))
        })
        .map(|l| l.strip_prefix("error: ").unwrap_or(l))
        .collect();
    // "the following required arguments were not provided:" heads a list, one per line.
    let mut line = String::new();
    let mut listing = false;
    for part in parts {
        let sep = match (line.is_empty(), listing) {
            (true, _) => "",
            (false, true) if !part.starts_with("tip:") => {
                if line.ends_with(':') {
                    " "
                } else {
                    ", "
                }
            }
            _ => "; ",
        };
        listing = part.ends_with(':') || (listing && !part.starts_with("tip:"));
        line.push_str(sep);
        line.push_str(part);
    }
    // Unsigned options read "-1" as a digit they cannot parse.
    let line = line.replace(
        ": invalid digit found in string",
        ": not a whole number of 0 or more",
    );
    format!("{line}; see --help")
}

/// `msg` with every long number written in scientific notation: messages quote option values
/// with `{}`, which writes 1e308 as 309 digits. Numbers of up to [`LONGEST_NUMBER_DIGITS`]
/// digits are kept as written: seeds, and file names of epoch times in nanoseconds
/// (`1732712345.123456789.png`), which must stay the names they are.
fn short_numbers(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(start) = rest.find(|c: char| c.is_ascii_digit()) {
        out.push_str(&rest[..start]);
        let len = rest[start..]
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(rest.len() - start);
        let number = rest[start..start + len].trim_end_matches('.');
        let digits = number.chars().filter(char::is_ascii_digit).count();
        match number.parse::<f64>() {
            Ok(v) if digits > LONGEST_NUMBER_DIGITS => out.push_str(&format!("{v:e}")),
            _ => out.push_str(number),
        }
        rest = &rest[start + number.len()..];
    }
    out.push_str(rest);
    out
}

/// `msg` with every quoted text of more than [`LONGEST_QUOTE`] characters cut short: errors
/// quote what they read (a header, a field), which in a file of the wrong kind can be a
/// whole binary line.
fn short_quotes(msg: &str) -> String {
    let parts: Vec<&str> = msg.split('"').collect();
    let cut = parts
        .iter()
        .enumerate()
        .map(|(i, part)| {
            let quoted = i % 2 == 1 && i + 1 < parts.len();
            let n = part.chars().count();
            if quoted && n > LONGEST_QUOTE {
                let head: String = part.chars().take(LONGEST_QUOTE / 2).collect();
                format!("{head}… ({n} characters)")
            } else {
                (*part).to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\"");
    // Quotes inside the quoted text itself can pair up wrongly: the whole is bounded too.
    let n = cut.chars().count();
    if n > LONGEST_MESSAGE {
        let head: String = cut.chars().take(LONGEST_MESSAGE).collect();
        return format!("{head}… (cut at {LONGEST_MESSAGE} of {n} characters)");
    }
    cut
}

/// The most characters of an error message shown.
const LONGEST_MESSAGE: usize = 3000;

/// The most digits of a number an error shows as written.
const LONGEST_NUMBER_DIGITS: usize = 24;

/// The most characters of a quoted text an error shows.
const LONGEST_QUOTE: usize = 120;

fn main() {
    // First, before any thread starts: they all inherit the blocked interrupt signals.
    output::discard_on_interrupt();
    if let Some(warning) = blas::one_thread_per_call() {
        eprintln!("{warning}");
    }
    // Rust ignores SIGPIPE, so a write into a closed pipe is an error that `say!` and `tell!`
    // pass over: the command runs to its end and commits its files.
    let command = negative_numbers_are_values(Cli::command());
    output::learn_value_options(&command);
    let matches = command.try_get_matches().unwrap_or_else(|e| usage_error(e));
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| usage_error(e));
    let result = match cli.command {
        Command::Synth(SynthCommand::Calib(a)) => cmd::synth_calib::run(a),
        Command::Synth(SynthCommand::CheckCalib(a)) => cmd::synth_calib::run_check(a),
        Command::Synth(SynthCommand::Track(a)) => cmd::synth_track::run(a),
        Command::Synth(SynthCommand::Experiment(a)) => cmd::synth_experiment::run(a),
        Command::Synth(SynthCommand::Lrf(a)) => cmd::synth_lrf::run(a),
        Command::Synth(SynthCommand::Arena(a)) => cmd::synth_arena::run(a),
        Command::Arena(a) => cmd::arena::run(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::Dataset(a) => cmd::dataset::run(a),
        Command::Train(a) => cmd::train::run(a),
        Command::Correct(a) => cmd::correct::run(a),
        Command::Evaluate(a) => cmd::evaluate::run(a),
        Command::Lrf(c) => cmd::lrf::run(c),
        Command::Report(a) => cmd::report::run(a),
    };
    // Outputs appear together when the command succeeds, and not at all when it fails.
    let result = result.and_then(|()| Ok(output::commit()?));
    if let Err(e) = result {
        output::discard();
        // One line: what was wrong, with the chain of causes joined (a cause that the
        // message already quotes, as typed errors quote their I/O source, only once).
        let mut msg = String::new();
        for cause in e.chain().map(|c| c.to_string()) {
            if msg.is_empty() {
                msg = cause;
            } else if !msg.contains(&cause) {
                msg = format!("{msg}: {cause}");
            }
        }
        tell!("odocal: error: {}", short_quotes(&short_numbers(&msg)));
        std::process::exit(2);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn usage_errors_are_one_line() {
        let clap_text = "error: unexpected argument '--tagid' found\n\n  tip: a similar argument exists: '--tag-id'\n\nUsage: odocal track --tag-id <TAG_ID> --out <OUT> <VIDEO>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            super::one_line_usage_error(clap_text),
            "unexpected argument '--tagid' found; tip: a similar argument exists: '--tag-id'; see --help"
        );
        let missing = "error: the following required arguments were not provided:\n  --out <OUT>\n  <VIDEO>\n\nUsage: odocal track --out <OUT> <VIDEO>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            super::one_line_usage_error(missing),
            "the following required arguments were not provided: --out <OUT>, <VIDEO>; see --help"
        );
        let negative = "error: invalid value '-1' for '--frames <FRAMES>': invalid digit found in string\n\nFor more information, try '--help'.\n";
        assert_eq!(
            super::one_line_usage_error(negative),
            "invalid value '-1' for '--frames <FRAMES>': not a whole number of 0 or more; see --help"
        );
    }

    #[test]
    fn long_numbers_and_quotes_are_shortened_and_others_kept() {
        let long = format!("--speed-max {}: need 0 < min", 1e308);
        assert_eq!(
            super::short_numbers(&long),
            "--speed-max 1e308: need 0 < min"
        );
        let tiny = format!("x {} s.", 1e-30);
        assert_eq!(super::short_numbers(&tiny), "x 1e-30 s.");
        let kept = "run001.csv:12:3: 0.25 m, 1.5e3 mm, v2.0.";
        assert_eq!(super::short_numbers(kept), kept);
        let long = format!("f.csv:1:1: header is \"{}\", not \"t\"", "x".repeat(500));
        let cut = super::short_quotes(&long);
        assert_eq!(
            cut,
            format!(
                "f.csv:1:1: header is \"{}… (500 characters)\", not \"t\"",
                "x".repeat(60)
            )
        );
        assert_eq!(super::short_quotes("an \"odd quote"), "an \"odd quote");
        let unpaired = format!("\"a\"b\"{}", "y".repeat(5000));
        assert!(super::short_quotes(&unpaired).ends_with("(cut at 3000 of 5005 characters)"));
        let frame = "frames/1732712345.123456789.png: not an image";
        assert_eq!(super::short_numbers(frame), frame);
        let seed = "--seed 18446744073709551615";
        assert_eq!(super::short_numbers(seed), seed);
    }

    /// `--max-clock-offset-s` has no clap default (giving it without `--arena` is refused), so
    /// its help states the default by hand: it must be the one the code uses.
    #[test]
    fn the_clock_offset_default_in_the_help_is_the_one_used() {
        use clap::CommandFactory;
        let mut cli = super::Cli::command();
        let track = cli
            .find_subcommand_mut("track")
            .expect("odocal has a track command");
        let help = track.render_long_help().to_string();
        let at = help
            .find("--max-clock-offset-s")
            .expect("track has --max-clock-offset-s");
        let want = format!(
            "[default: {}]",
            super::cmd::track_arena::DEFAULT_MAX_CLOCK_OFFSET_S
        );
        let next = help[at..].find("\n      --").map_or(help.len(), |i| at + i);
        assert!(help[at..next].contains(&want), "{}", &help[at..next]);
    }
}
