//! JSON files that say what they are: every JSON file odocal writes starts with
//! `"format": "odocal-…/N"`, and every reader checks it first, so passing the wrong file
//! (a model where a camera belongs) fails with a message saying so instead of a confusing
//! "missing field" from deep inside the document.

use serde::de::DeserializeOwned;

use crate::file_error::FileError;

/// Parses JSON `text` that must carry `"format": expected`, then deserialises it into `T`.
/// `name` (the file) starts every message; `hint` follows a wrong or missing format tag and
/// should say which file is wanted (e.g. "pass a camera.json written by `odocal calibrate`").
/// A leading byte order mark is passed over ([`without_bom`]).
pub fn parse_tagged_json<T: DeserializeOwned>(
    text: &str,
    name: &str,
    expected: &str,
    hint: &str,
) -> Result<T, FileError> {
    let text = without_bom(text);
    let value = parse_json_value(text, name).map_err(|e| match e {
        FileError::Parse {
            path,
            line,
            column,
            message,
        } => FileError::Parse {
            path,
            line,
            column,
            message: format!("{message}; {hint}"),
        },
        other => other,
    })?;
    check_format_tag(&value, name, expected, hint)?;
    // Parsed again from the text (not the value) so that errors carry line and column.
    serde_json::from_str(text)
        .map_err(|e| FileError::parse(name, e.line() as u64, e.column() as u64, without_place(&e)))
}

/// A JSON error's message without serde_json's " at line L column C": the file's name
/// already leads with the place, and the message read it twice.
fn without_place(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let place = format!(" at line {} column {}", e.line(), e.column());
    text.strip_suffix(&place).unwrap_or(&text).to_string()
}

/// Reads the JSON file at `path` with [`parse_tagged_json`], naming the file in every message.
pub fn read_tagged_json<T: DeserializeOwned>(
    path: &std::path::Path,
    expected: &str,
    hint: &str,
) -> Result<T, FileError> {
    let text = crate::file_error::read_text(path)?;
    parse_tagged_json(&text, &path.display().to_string(), expected, hint)
}

/// `text` without a leading UTF-8 byte order mark: editors on Windows save JSON with one
/// after a hand edit, and the JSON parser would refuse it at line 1, column 1.
pub fn without_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// Parses JSON `text` into a generic value; syntax errors name the line and column. A
/// leading byte order mark is passed over ([`without_bom`]).
pub fn parse_json_value(text: &str, name: &str) -> Result<serde_json::Value, FileError> {
    serde_json::from_str(without_bom(text)).map_err(|e| {
        FileError::parse(
            name,
            e.line() as u64,
            e.column() as u64,
            format!("invalid JSON: {}", without_place(&e)),
        )
    })
}

/// Checks that a parsed JSON document carries `"format": expected` (see [`parse_tagged_json`]).
pub fn check_format_tag(
    value: &serde_json::Value,
    name: &str,
    expected: &str,
    hint: &str,
) -> Result<(), FileError> {
    match value.get("format").and_then(|f| f.as_str()) {
        Some(f) if f == expected => Ok(()),
        Some(f) => Err(FileError::content(
            name,
            format!("format is \"{f}\", expected \"{expected}\"; {hint}"),
        )),
        None => Err(FileError::content(
            name,
            format!("no \"format\" field, expected \"{expected}\"; {hint}"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize, Debug)]
    struct Doc {
        n: u32,
    }

    /// A model.json saved by a Windows editor after a hand edit was refused as "invalid JSON
    /// at line 1 column 1", where a manifest with the same mark was read.
    #[test]
    fn a_byte_order_mark_is_passed_over() {
        let ok: Doc =
            parse_tagged_json("\u{feff}{\"format\":\"x/1\",\"n\":3}", "a.json", "x/1", "h")
                .unwrap();
        assert_eq!(ok.n, 3);
        assert!(parse_json_value("\u{feff}[1]", "b.json").is_ok());
    }

    #[test]
    fn wrong_or_missing_tag_names_the_file() {
        let ok: Doc = parse_tagged_json(r#"{"format":"x/1","n":3}"#, "a.json", "x/1", "h").unwrap();
        assert_eq!(ok.n, 3);
        let e = parse_tagged_json::<Doc>(r#"{"format":"y/1","n":3}"#, "a.json", "x/1", "pass x")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.json: format is \"y/1\", expected \"x/1\"; pass x"
        );
        let e = parse_tagged_json::<Doc>(r#"{"n":3}"#, "a.json", "x/1", "h").unwrap_err();
        assert!(e.to_string().contains("no \"format\" field"));
        let e = parse_tagged_json::<Doc>("{\n\"format\":", "a.json", "x/1", "h").unwrap_err();
        assert!(e.to_string().starts_with("a.json:2:"), "{e}");
        let e = parse_tagged_json::<Doc>(r#"{"format":"x/1"}"#, "a.json", "x/1", "h").unwrap_err();
        assert!(e.to_string().contains("missing field `n`"), "{e}");
        // The place is named once, ahead of the message.
        let e = parse_tagged_json::<Doc>("{\"format\":\"x/1\",\n\"n\":true}", "a.json", "x/1", "h")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.json:2:8: invalid type: boolean `true`, expected u32"
        );
    }
}
