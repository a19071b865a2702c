//! The board options `odocal calibrate` and `odocal synth calib` share: which target is
//! printed, and a ChArUco board's markers.

use clap::Args as ClapArgs;
use odocal_calib::BoardSpec;

/// What is printed on the calibration board.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetArg {
    /// Black and white squares; every inner corner must be in view.
    Checkerboard,
    /// OpenCV's ChArUco board: ArUco markers in the white squares, so a board partly outside
    /// the image counts.
    Charuco,
}

/// `--target`, `--marker` and `--dictionary`.
#[derive(ClapArgs)]
pub struct TargetArgs {
    /// The board: `checkerboard` (--board counts inner corners) or `charuco` (--board counts
    /// squares, as OpenCV does; with --marker and --dictionary).
    #[arg(long, value_enum, default_value_t = TargetArg::Checkerboard)]
    pub target: TargetArg,
    /// ChArUco: side of one marker, metres (less than --square; `synth calib`: 3/4 of it).
    #[arg(long)]
    pub marker: Option<f64>,
    /// ChArUco: the markers' ArUco dictionary, OpenCV's name without DICT_ (e.g. 4X4_50, the
    /// default of `synth calib`).
    #[arg(long)]
    pub dictionary: Option<String>,
}

impl TargetArgs {
    /// The board spec from these options and `--board` / `--square`; `None` for `--board`
    /// takes `default_board` for a checkerboard and is an error for a ChArUco board unless
    /// `charuco_defaults` gives the board, marker and dictionary to use.
    pub fn board_spec(
        &self,
        board: Option<&str>,
        square_m: f64,
        default_board: &str,
        charuco_defaults: Option<(&str, f64, &str)>,
    ) -> anyhow::Result<BoardSpec> {
        match self.target {
            TargetArg::Checkerboard => {
                if self.marker.is_some() || self.dictionary.is_some() {
                    anyhow::bail!(
                        "--marker and --dictionary describe a ChArUco board; pass --target charuco with them, or leave them out for a checkerboard"
                    );
                }
                Ok(BoardSpec::parse(board.unwrap_or(default_board), square_m)?)
            }
            TargetArg::Charuco => {
                let (db, dm, dd) = match charuco_defaults {
                    Some((b, m, d)) => (Some(b), Some(m), Some(d)),
                    None => (None, None, None),
                };
                let board = board.or(db).ok_or_else(|| {
                    anyhow::anyhow!(
                        "--target charuco needs --board COLSxROWS counting the board's squares, e.g. 11x8"
                    )
                })?;
                let marker = self.marker.or(dm).ok_or_else(|| {
                    anyhow::anyhow!(
                        "--target charuco needs --marker, the side of one printed marker in metres (e.g. 0.03)"
                    )
                })?;
                let dictionary = self.dictionary.as_deref().or(dd).ok_or_else(|| {
                    anyhow::anyhow!(
                        "--target charuco needs --dictionary, the markers' ArUco dictionary (e.g. 4X4_50)"
                    )
                })?;
                Ok(BoardSpec::parse_charuco(
                    board, square_m, marker, dictionary,
                )?)
            }
        }
    }
}
