//! The error every shared file reader returns: what was wrong, in which file, and where.

use thiserror::Error;

/// Why reading one of odocal's files failed. Messages start with the file name, then the
/// 1-based line and column where there is one, then what was wrong and what to do.
#[derive(Debug, Error)]
pub enum FileError {
    /// The file could not be read.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// An output could not be written (its folder made, its file written or moved into place).
    #[error("cannot write {path}")]
    Write {
        /// The file or folder.
        path: String,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A malformed value, with its position (1-based line and column).
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// 1-based line number.
        line: u64,
        /// 1-based column (CSV field or JSON character).
        column: u64,
        /// What was wrong and what to do.
        message: String,
    },
    /// A file that parses but whose content is unusable (wrong format tag, too few rows, ...).
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: String,
        /// What was wrong and what to do.
        message: String,
    },
}

impl FileError {
    /// Builds a [`FileError::Parse`].
    pub fn parse(path: &str, line: u64, column: u64, message: impl Into<String>) -> Self {
        Self::Parse {
            path: path.to_string(),
            line,
            column,
            message: message.into(),
        }
    }

    /// Builds a [`FileError::Content`].
    pub fn content(path: &str, message: impl Into<String>) -> Self {
        Self::Content {
            path: path.to_string(),
            message: message.into(),
        }
    }
}

/// Reads a whole text file, mapping the error to [`FileError::Io`] with the file's name; a
/// file that is not text (a video or an image given in a CSV's or JSON's place) is named as
/// such, not as a stream without valid UTF-8.
pub fn read_text(path: &std::path::Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::InvalidData {
            FileError::content(
                &path.display().to_string(),
                "this is not a text file (binary data: a video, an image or an archive?); give the CSV or JSON file asked for",
            )
        } else {
            FileError::Io {
                path: path.display().to_string(),
                source,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A video given where a camera.json or a CSV belongs is named as not text.
    #[test]
    fn a_binary_file_is_named_as_not_text() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("video.avi");
        std::fs::write(&path, [b'R', b'I', b'F', b'F', 0xff, 0xfe, 0x00, 0x80]).expect("write");
        let e = read_text(&path).expect_err("binary").to_string();
        assert!(
            e.ends_with("video.avi: this is not a text file (binary data: a video, an image or an archive?); give the CSV or JSON file asked for"),
            "{e}"
        );
        std::fs::write(&path, "t,x\n").expect("write");
        assert_eq!(read_text(&path).expect("text"), "t,x\n");
    }
}
