//! CSV tables as odocal's text files use them: a header row, then data rows of numbers.
//! Blank rows and `#` comments are skipped and fields trimmed, so hand-edited files read
//! the same as written ones; every error names the line and column.

use crate::file_error::FileError;

/// A CSV text split into its header and data rows, each with its 1-based line number.
pub struct CsvTable {
    /// Line and fields of the header.
    pub header: (u64, csv::StringRecord),
    /// Line and fields of each data row.
    pub rows: Vec<(u64, csv::StringRecord)>,
}

/// Reads `text` as a [`CsvTable`] (rows of any length); `None` when it has no header (an
/// empty file). `name` is used in error messages.
pub fn csv_table(text: &str, name: &str) -> Result<Option<CsvTable>, FileError> {
    // The csv crate leaves `#` comments and blank lines out of its line numbers, so comment
    // lines are emptied here and a record's line is counted from its byte offset.
    let uncommented: String = text
        .split_inclusive('\n')
        .map(|l| {
            if l.starts_with('#') {
                &l[l.trim_end_matches(['\r', '\n']).len()..]
            } else {
                l
            }
        })
        .collect();
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(uncommented.as_bytes());
    let lines = LineIndex::new(&uncommented);
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| csv_error(name, &e))?;
        if rec.iter().all(|f| f.is_empty()) {
            continue;
        }
        let line = rec.position().map(|p| lines.line_of_byte(p.byte()));
        rows.push((line.unwrap_or(0), rec));
    }
    if rows.is_empty() {
        return Ok(None);
    }
    let header = rows.remove(0);
    // A spreadsheet set to a decimal comma writes `;` between columns: the whole header is
    // then one column, which each reader would name as a column it does not know.
    if let (1, Some(h)) = (header.1.len(), header.1.get(0)) {
        if h.contains(';') {
            return Err(FileError::parse(
                name,
                header.0,
                1,
                format!(
                    "the header \"{h}\" is separated by semicolons, but odocal reads comma-separated CSV; separate the columns with commas (and write decimals with a point)"
                ),
            ));
        }
    }
    Ok(Some(CsvTable { header, rows }))
}

/// [`csv_table`] for a file that must have a header: an empty one is an error saying it is
/// an empty `what` ("empty pose log (no header)").
pub fn csv_table_with_header(text: &str, name: &str, what: &str) -> Result<CsvTable, FileError> {
    csv_table(text, name)?
        .ok_or_else(|| FileError::content(name, format!("empty {what} (no header)")))
}

/// A text file format: parsed from text (`name` starts every message) and read from a path
/// with the same messages.
pub trait TextFormat: Sized {
    /// Parses the file's text.
    fn parse(text: &str, name: &str) -> Result<Self, FileError>;

    /// Reads and parses the file at `path`.
    fn read(path: &std::path::Path) -> Result<Self, FileError> {
        let text = crate::file_error::read_text(path)?;
        Self::parse(&text, &path.display().to_string())
    }
}

/// Parses a data row of exactly `N` finite numbers; errors name the line and column.
pub fn numeric_row<const N: usize>(
    name: &str,
    line: u64,
    rec: &csv::StringRecord,
) -> Result<[f64; N], FileError> {
    if rec.len() != N {
        return Err(FileError::parse(
            name,
            line,
            rec.len().min(N) as u64 + 1,
            format!("expected {N} fields, found {}", rec.len()),
        ));
    }
    let mut vals = [0.0; N];
    for (c, field) in rec.iter().enumerate() {
        let col = c as u64 + 1;
        let v: f64 = field.parse().map_err(|_| {
            FileError::parse(name, line, col, format!("\"{field}\" is not a number"))
        })?;
        if !v.is_finite() {
            return Err(FileError::parse(
                name,
                line,
                col,
                format!("\"{field}\" is not a finite number"),
            ));
        }
        vals[c] = v;
    }
    Ok(vals)
}

/// The lines of a text, for the 1-based line numbers of records by their byte offsets
/// (indexed once: counting from the start for every record is quadratic in a large file).
pub struct LineIndex<'a> {
    text: &'a [u8],
    newlines: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    /// Indexes `text`'s line ends.
    pub fn new(text: &'a str) -> Self {
        let text = text.as_bytes();
        let newlines = (0..text.len()).filter(|&i| text[i] == b'\n').collect();
        Self { text, newlines }
    }

    /// 1-based line number of the record starting at byte offset `byte`. The offset the csv
    /// crate gives can point at blank lines before the record, and the crate's own line count
    /// runs one short after a CRLF line, so the line ends are counted here.
    pub fn line_of_byte(&self, byte: u64) -> u64 {
        let mut end = (byte as usize).min(self.text.len());
        while end < self.text.len() && matches!(self.text[end], b'\n' | b'\r') {
            end += 1;
        }
        self.newlines.partition_point(|&i| i < end) as u64 + 1
    }
}

/// Maps a csv crate error to a positioned parse error.
pub fn csv_error(name: &str, e: &csv::Error) -> FileError {
    // The error carries no text to count lines in; its record's line stands.
    let line = e.position().map(|p| p.line()).unwrap_or(0);
    FileError::parse(name, line, 1, format!("malformed CSV: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_keep_their_line_numbers() {
        let t = csv_table("# comment\na,b\n\n1, 2\n3,4\n", "f.csv")
            .unwrap()
            .unwrap();
        assert_eq!(t.header.0, 2);
        assert_eq!(t.rows[0].0, 4);
        let v: [f64; 2] = numeric_row("f.csv", t.rows[0].0, &t.rows[0].1).unwrap();
        assert_eq!(v, [1.0, 2.0]);
        // Windows line ends count as one line each, blank lines before a row too.
        let t = csv_table("a,b\r\n1,2\r\n\r\n# c\r\n3,4\r\n", "f.csv")
            .unwrap()
            .unwrap();
        assert_eq!((t.rows[0].0, t.rows[1].0), (2, 5));
        assert!(csv_table("\n# only a comment\n", "f.csv")
            .unwrap()
            .is_none());
    }

    #[test]
    fn bad_fields_are_located() {
        let t = csv_table("a,b\n1,x\n1\n1,inf\n", "f.csv").unwrap().unwrap();
        let e = |i: usize| {
            numeric_row::<2>("f.csv", t.rows[i].0, &t.rows[i].1)
                .unwrap_err()
                .to_string()
        };
        assert_eq!(e(0), "f.csv:2:2: \"x\" is not a number");
        assert_eq!(e(1), "f.csv:3:2: expected 2 fields, found 1");
        assert_eq!(e(2), "f.csv:4:2: \"inf\" is not a finite number");
    }
}
