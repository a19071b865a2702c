//! The report document: sections of text, inline SVG figures and tables, as one HTML file.

use std::fmt::Write;

/// A table with a caption (units go in the header cells).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Caption above the table.
    pub caption: String,
    /// Column headers.
    pub header: Vec<String>,
    /// Rows of cells (already formatted, units in the header).
    pub rows: Vec<Vec<String>>,
}

/// One item of a section.
#[derive(Debug, Clone, PartialEq)]
pub enum Block {
    /// A paragraph of text.
    Text(String),
    /// A rendered chart: file stem for `--svg-dir`, caption, SVG text.
    Figure {
        /// File stem when written on its own (`<name>.svg`).
        name: String,
        /// Caption under the figure.
        caption: String,
        /// The SVG document.
        svg: String,
    },
    /// A table.
    Table(Table),
    /// A short note (what is missing, how a figure was made).
    Note(String),
}

/// A titled part of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Anchor id.
    pub id: String,
    /// Heading.
    pub title: String,
    /// Content in order.
    pub blocks: Vec<Block>,
}

impl Section {
    /// An empty section.
    pub fn new(id: &str, title: &str) -> Self {
        Self {
            id: id.to_string(),
            title: title.to_string(),
            blocks: Vec::new(),
        }
    }

    /// Number of figures in the section.
    pub fn n_figures(&self) -> usize {
        self.blocks
            .iter()
            .filter(|b| matches!(b, Block::Figure { .. }))
            .count()
    }
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    /// Document title.
    pub title: String,
    /// Lines under the title (inputs used).
    pub intro: Vec<String>,
    /// Sections with content.
    pub sections: Vec<Section>,
    /// Sections left out: (title, one-line reason).
    pub omitted: Vec<(String, String)>,
}

/// Escapes text for HTML content and attributes.
pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1180px;margin:1em auto;padding:0 1em;color:#222;line-height:1.4}\
h1{border-bottom:2px solid #0072b2}h2{margin-top:1.8em;border-bottom:1px solid #ccc}\
figure{display:inline-block;margin:.5em 1em .8em 0;vertical-align:top}figcaption{font-size:.9em;color:#444;max-width:760px}\
figure svg{max-width:100%;height:auto;border:1px solid #eee}\
table{border-collapse:collapse;margin:.6em 0 1em;font-size:.92em}caption{text-align:left;font-weight:bold;padding:.3em 0}\
th,td{border:1px solid #bbb;padding:.25em .6em;text-align:right}th{background:#f0f4f8}td:first-child,th:first-child{text-align:left}\
.note{color:#7a5a00;background:#fff8e1;padding:.3em .6em;border-left:3px solid #e69f00}\
nav a{margin-right:1em}";

impl Report {
    /// All figures as (file stem, SVG text).
    pub fn figures(&self) -> Vec<(&str, &str)> {
        self.sections
            .iter()
            .flat_map(|s| &s.blocks)
            .filter_map(|b| match b {
                Block::Figure { name, svg, .. } => Some((name.as_str(), svg.as_str())),
                _ => None,
            })
            .collect()
    }

    /// The self-contained HTML document (no scripts, no external resources).
    pub fn to_html(&self) -> String {
        let mut h = String::new();
        let _ = write!(
            h,
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
            escape(&self.title),
            escape(&self.title)
        );
        for line in &self.intro {
            let _ = writeln!(h, "<p>{}</p>", escape(line));
        }
        if !self.sections.is_empty() {
            h.push_str("<nav>");
            for s in &self.sections {
                let _ = write!(h, "<a href=\"#{}\">{}</a>", escape(&s.id), escape(&s.title));
            }
            h.push_str("</nav>\n");
        }
        if !self.omitted.is_empty() {
            h.push_str("<h2 id=\"omitted\">Sections left out</h2>\n<ul>\n");
            for (t, why) in &self.omitted {
                let _ = writeln!(
                    h,
                    "<li class=\"note\"><b>{}</b>: {}</li>",
                    escape(t),
                    escape(why)
                );
            }
            h.push_str("</ul>\n");
        }
        for s in &self.sections {
            let _ = writeln!(
                h,
                "<section id=\"{}\">\n<h2>{}</h2>",
                escape(&s.id),
                escape(&s.title)
            );
            for b in &s.blocks {
                match b {
                    Block::Text(t) => {
                        let _ = writeln!(h, "<p>{}</p>", escape(t));
                    }
                    Block::Note(t) => {
                        let _ = writeln!(h, "<p class=\"note\">{}</p>", escape(t));
                    }
                    Block::Figure { name, caption, svg } => {
                        let _ = writeln!(
                            h,
                            "<figure id=\"fig-{}\">\n{}\n<figcaption>{}</figcaption>\n</figure>",
                            escape(name),
                            strip_xml_decl(svg),
                            escape(caption)
                        );
                    }
                    Block::Table(t) => {
                        h.push_str("<table>\n");
                        let _ = writeln!(h, "<caption>{}</caption>", escape(&t.caption));
                        h.push_str("<tr>");
                        for c in &t.header {
                            let _ = write!(h, "<th>{}</th>", escape(c));
                        }
                        h.push_str("</tr>\n");
                        for r in &t.rows {
                            h.push_str("<tr>");
                            for c in r {
                                let _ = write!(h, "<td>{}</td>", escape(c));
                            }
                            h.push_str("</tr>\n");
                        }
                        h.push_str("</table>\n");
                    }
                }
            }
            h.push_str("</section>\n");
        }
        h.push_str("</body>\n</html>\n");
        h
    }
}

/// Drops an `<?xml ...?>` declaration so the SVG can be inlined in HTML.
fn strip_xml_decl(svg: &str) -> &str {
    let t = svg.trim_start();
    if t.starts_with("<?xml") {
        match t.find("?>") {
            Some(i) => t[i + 2..].trim_start(),
            None => t,
        }
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_escapes_and_inlines() {
        let mut s = Section::new("a", "A <b>");
        s.blocks.push(Block::Text("x < y & z".into()));
        s.blocks.push(Block::Figure {
            name: "f".into(),
            caption: "cap".into(),
            svg: "<?xml version=\"1.0\"?>\n<svg></svg>".into(),
        });
        s.blocks.push(Block::Table(Table {
            caption: "t".into(),
            header: vec!["h (m)".into()],
            rows: vec![vec!["1".into()]],
        }));
        let r = Report {
            title: "T".into(),
            intro: vec![],
            sections: vec![s],
            omitted: vec![("L".into(), "no input".into())],
        };
        let h = r.to_html();
        assert!(h.contains("A &lt;b&gt;"));
        assert!(h.contains("x &lt; y &amp; z"));
        assert!(h.contains("<figure id=\"fig-f\">\n<svg></svg>"));
        assert!(!h.contains("<?xml"));
        assert!(h.contains("<th>h (m)</th>"));
        assert!(h.contains("no input"));
        assert!(!h.contains("<script"));
        assert_eq!(r.figures().len(), 1);
    }
}
