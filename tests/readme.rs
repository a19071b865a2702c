//! The README's examples are run, so they cannot rot (issue 7).
//!
//! Convention in README.md — every shell block (```sh, ```bash, ```shell) carries a marker, an
//! HTML comment (invisible on GitHub) on the line right before its opening fence:
//!
//! - `<!-- readme-test: run -->`: the block is run. All run blocks are run in README order, each
//!   with `bash -euo pipefail -c <block>`, in one temporary working directory shared by all of
//!   them (so a block uses what earlier blocks wrote), with the directory of the `odocal` built
//!   for this test first on `PATH`.
//! - `<!-- readme-test: skip -->`: the block is not run (setup and development commands such as
//!   `make demo`, and anything that needs hardware or minutes).
//! - `<!-- readme-test: output -->` before a ```text block: the output the README shows for the
//!   nearest run block above it. It is compared with what that block really printed, stdout and
//!   stderr together as a terminal shows them (both go to one file, in write order):
//!   - line by line, in the same order, with no extra or missing lines;
//!   - every number (`-0.11`, `1280`, `1e-4`) matches any number, and every run of white space
//!     matches any run of white space, so figures and column widths may change;
//!   - a line that is just `...` stands for any number of lines (also none), and `...` inside a
//!     line stands for any text, so long outputs can be shown in part;
//!   - trailing white space is ignored.
//!
//! A shell block without a marker fails the test, so no new example can silently go unrun.
//! When a block fails, the message names its line in README.md, shows its output (with the
//! command's stderr) and keeps the working directory for inspection.
//!
//! Shown lines whose figures differ from the real run are listed on stderr (seen with
//! `-- --nocapture`; the test still passes). `README_TEST_UPDATE=1 cargo test --test readme` writes the real lines into README.md
//! (in lines with an inline `...` only the numbers), so the figures shown stay those of real runs;
//! `README_TEST_SHOW=1 cargo test --test readme -- --nocapture` prints every block's whole real
//! output (to paste into README.md after a deliberate change of a command's output).

use std::fs::File;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

/// What a marker asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Marker {
    Run,
    Skip,
    Output,
}

/// One fenced block of README.md.
#[derive(Debug)]
struct Block {
    /// Line of the opening fence (1-based).
    line: usize,
    /// Info string of the fence (`sh`, `text`, ...).
    lang: String,
    /// The block's text, one entry per line.
    body: Vec<String>,
    /// The marker right before the fence, if any.
    marker: Option<Marker>,
}

/// A run block and the output the README shows for it (if any).
struct Example {
    line: usize,
    script: String,
    shown: Option<(usize, Vec<String>)>,
}

fn parse_marker(line: &str) -> Option<Result<Marker, String>> {
    let inner = line
        .trim()
        .strip_prefix("<!--")?
        .strip_suffix("-->")?
        .trim()
        .strip_prefix("readme-test:")?
        .trim();
    Some(match inner {
        "run" => Ok(Marker::Run),
        "skip" => Ok(Marker::Skip),
        "output" => Ok(Marker::Output),
        other => Err(format!(
            "unknown readme-test marker `{other}` (run, skip or output)"
        )),
    })
}

/// The number of backticks and the info string of an opening code fence (CommonMark: at least
/// three backticks, an info string without backticks).
fn opening_fence(line: &str) -> Option<(usize, &str)> {
    let t = line.trim_start();
    let ticks = t.len() - t.trim_start_matches('`').len();
    let info = &t[ticks..];
    (ticks >= 3 && !info.contains('`')).then_some((ticks, info))
}

/// Fenced blocks of a Markdown text with the marker of each.
fn parse_blocks(text: &str, name: &str) -> Result<Vec<Block>, String> {
    let mut blocks = Vec::new();
    let mut pending: Option<(usize, Marker)> = None;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    while let Some((n, line)) = lines.next() {
        if let Some(m) = parse_marker(line) {
            let m = m.map_err(|e| format!("{name} line {n}: {e}"))?;
            if let Some((p, _)) = pending {
                return Err(format!(
                    "{name} line {p}: readme-test marker not followed by a fenced block"
                ));
            }
            pending = Some((n, m));
            continue;
        }
        if let Some((ticks, info)) = opening_fence(line) {
            let mut body = Vec::new();
            let mut closed = false;
            for (_, l) in lines.by_ref() {
                let l_trim = l.trim();
                if l_trim.len() >= ticks && l_trim.chars().all(|c| c == '`') {
                    closed = true;
                    break;
                }
                body.push(l.to_string());
            }
            if !closed {
                return Err(format!("{name} line {n}: fenced block never closed"));
            }
            blocks.push(Block {
                line: n,
                lang: info.trim().to_string(),
                body,
                marker: pending.take().map(|(_, m)| m),
            });
            continue;
        }
        if let Some((p, _)) = pending {
            if !line.trim().is_empty() {
                return Err(format!(
                    "{name} line {p}: readme-test marker must be right before a fenced block"
                ));
            }
        }
    }
    if let Some((p, _)) = pending {
        return Err(format!(
            "{name} line {p}: readme-test marker not followed by a fenced block"
        ));
    }
    Ok(blocks)
}

fn is_shell(lang: &str) -> bool {
    matches!(lang, "sh" | "bash" | "shell" | "console")
}

/// The run blocks in order, each with the output the README shows for it.
fn examples(blocks: &[Block], name: &str) -> Result<Vec<Example>, String> {
    let mut out: Vec<Example> = Vec::new();
    for b in blocks {
        match (b.marker, is_shell(&b.lang)) {
            (None, true) => {
                return Err(format!(
                    "{name} line {}: ```{} block without a marker: put \
                     `<!-- readme-test: run -->` (or `skip`, saying why in the text) before it",
                    b.line, b.lang
                ))
            }
            (None, false) | (Some(Marker::Skip), true) => {}
            (Some(Marker::Run), true) => out.push(Example {
                line: b.line,
                script: b.body.join("\n"),
                shown: None,
            }),
            (Some(Marker::Output), false) if b.lang == "text" => {
                let Some(last) = out.last_mut() else {
                    return Err(format!(
                        "{name} line {}: output block before any run block",
                        b.line
                    ));
                };
                if let Some((l, _)) = last.shown {
                    return Err(format!(
                        "{name} line {}: the run block at line {} already has its output at line {l}",
                        b.line, last.line
                    ));
                }
                last.shown = Some((b.line, b.body.clone()));
            }
            (Some(m), _) => {
                return Err(format!(
                    "{name} line {}: marker {m:?} does not fit a ```{} block \
                     (run/skip go on shell blocks, output on text blocks)",
                    b.line, b.lang
                ))
            }
        }
    }
    Ok(out)
}

/// One element of a shown line.
#[derive(Debug, PartialEq)]
enum Pat {
    /// Any number.
    Num,
    /// One or more white-space characters.
    Space,
    /// Any text (`...` inside a line).
    Any,
    /// This character.
    Lit(char),
}

/// Length in bytes of the number starting at the beginning of `s` (0 if none):
/// `[-+]?\d+(\.\d+)?([eE][-+]?\d+)?`.
fn number_len(s: &str) -> usize {
    let b = s.as_bytes();
    let digits = |mut i: usize| {
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        (i, i > start)
    };
    let mut i = 0;
    if i < b.len() && (b[i] == b'-' || b[i] == b'+') {
        i += 1;
    }
    let (j, any) = digits(i);
    if !any {
        return 0;
    }
    i = j;
    if i + 1 < b.len() && b[i] == b'.' && b[i + 1].is_ascii_digit() {
        i = digits(i + 1).0;
    }
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        let mut k = i + 1;
        if k < b.len() && (b[k] == b'-' || b[k] == b'+') {
            k += 1;
        }
        let (m, any) = digits(k);
        if any {
            i = m;
        }
    }
    i
}

fn compile(shown: &str) -> Vec<Pat> {
    let mut pats = Vec::new();
    let mut rest = shown.trim_end();
    while let Some(c) = rest.chars().next() {
        if let Some(r) = rest.strip_prefix("...") {
            pats.push(Pat::Any);
            rest = r;
        } else if c.is_whitespace() {
            pats.push(Pat::Space);
            rest = rest.trim_start();
        } else {
            let n = number_len(rest);
            if n > 0 {
                pats.push(Pat::Num);
                rest = &rest[n..];
            } else {
                pats.push(Pat::Lit(c));
                rest = &rest[c.len_utf8()..];
            }
        }
    }
    pats
}

/// Does `s` match `pats`? On success `nums` holds the numbers of `s` that matched `Pat::Num`.
fn match_pats<'a>(pats: &[Pat], s: &'a str, nums: &mut Vec<&'a str>) -> bool {
    let Some((p, rest)) = pats.split_first() else {
        return s.is_empty();
    };
    match p {
        Pat::Lit(c) => s
            .strip_prefix(*c)
            .is_some_and(|s| match_pats(rest, s, nums)),
        Pat::Num => {
            let n = number_len(s);
            if n == 0 {
                return false;
            }
            nums.push(&s[..n]);
            let ok = match_pats(rest, &s[n..], nums);
            if !ok {
                nums.pop();
            }
            ok
        }
        Pat::Space => {
            let t = s.trim_start();
            t.len() < s.len() && match_pats(rest, t, nums)
        }
        Pat::Any => s
            .char_indices()
            .map(|(i, _)| i)
            .chain(std::iter::once(s.len()))
            .any(|i| match_pats(rest, &s[i..], nums)),
    }
}

/// The real line's numbers in the places of the shown line's numbers, if the lines match.
fn matched_numbers<'a>(shown: &str, real: &'a str) -> Option<Vec<&'a str>> {
    let mut nums = Vec::new();
    match_pats(&compile(shown), real.trim_end(), &mut nums).then_some(nums)
}

/// Does one real output line match one shown line?
fn line_matches(shown: &str, real: &str) -> bool {
    matched_numbers(shown, real).is_some()
}

/// The shown line with its numbers replaced, in order, by `nums`.
fn with_numbers(shown: &str, nums: &[&str]) -> String {
    let mut out = String::new();
    let mut nums = nums.iter();
    let mut rest = shown.trim_end();
    while let Some(c) = rest.chars().next() {
        if let Some(r) = rest.strip_prefix("...") {
            out.push_str("...");
            rest = r;
            continue;
        }
        let n = number_len(rest);
        if n > 0 {
            out.push_str(nums.next().copied().unwrap_or(&rest[..n]));
            rest = &rest[n..];
        } else {
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}

fn is_elision(shown: &str) -> bool {
    shown.trim() == "..."
}

/// Matches shown lines against real lines: for each shown line the index of the real line it
/// matched (`None` for a `...` line); on failure the index of the furthest shown line that could
/// not be matched.
fn match_lines(shown: &[String], real: &[&str]) -> Result<Vec<Option<usize>>, usize> {
    struct State {
        failed: std::collections::HashSet<(usize, usize)>,
        furthest: usize,
        matched: Vec<Option<usize>>,
    }
    fn go(shown: &[String], si: usize, real: &[&str], ri: usize, st: &mut State) -> bool {
        if st.failed.contains(&(si, ri)) {
            return false;
        }
        st.furthest = st.furthest.max(si);
        let ok = if si == shown.len() {
            ri == real.len()
        } else if is_elision(&shown[si]) {
            (ri..=real.len()).any(|r| go(shown, si + 1, real, r, st))
        } else {
            let ok = ri < real.len()
                && line_matches(&shown[si], real[ri])
                && go(shown, si + 1, real, ri + 1, st);
            if ok {
                st.matched[si] = Some(ri);
            }
            ok
        };
        if !ok {
            st.failed.insert((si, ri));
        }
        ok
    }
    let mut st = State {
        failed: std::collections::HashSet::new(),
        furthest: 0,
        matched: vec![None; shown.len()],
    };
    if go(shown, 0, real, 0, &mut st) {
        Ok(st.matched)
    } else {
        Err(st.furthest)
    }
}

/// A shown output line whose figures differ from the real output: (line in the file, shown
/// text, real text).
type Refresh = (usize, String, String);

fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// Runs one block in `dir`; returns (success, exit status text, output).
fn run_block(script: &str, dir: &Path, path_env: &str, log: &Path) -> (bool, String, String) {
    let out = File::create(log).expect("create the block's output file");
    let err = out.try_clone().expect("clone the output file handle");
    let status = Command::new("bash")
        .args(["-euo", "pipefail", "-c", script])
        .current_dir(dir)
        .env("PATH", path_env)
        .stdin(Stdio::null())
        .stdout(Stdio::from(out))
        .stderr(Stdio::from(err))
        .status()
        .expect("start bash");
    let text = std::fs::read_to_string(log).unwrap_or_default();
    (status.success(), status.to_string(), text)
}

/// Runs the examples of the Markdown text `md` (named `name` in messages) in order in one
/// temporary directory; returns how many ran and the shown lines (without `...`) whose figures
/// differ from the real output, or the message of the first failure. On failure the working
/// directory is kept (and named in the message) if `keep_on_failure`.
fn run_examples(
    md: &str,
    name: &str,
    keep_on_failure: bool,
) -> Result<(usize, Vec<Refresh>), String> {
    let blocks = parse_blocks(md, name)?;
    let examples = examples(&blocks, name)?;
    let bin = Path::new(env!("CARGO_BIN_EXE_odocal"));
    let bin_dir = bin.parent().expect("binary directory");
    let path_env = match std::env::var_os("PATH") {
        Some(p) => format!("{}:{}", bin_dir.display(), p.to_string_lossy()),
        None => bin_dir.display().to_string(),
    };
    let work = tempfile::Builder::new()
        .prefix("odocal-readme-")
        .tempdir()
        .expect("temporary directory");
    let logs = tempfile::tempdir().expect("temporary directory for outputs");
    let show = std::env::var_os("README_TEST_SHOW").is_some();
    let t_all = Instant::now();
    let mut refresh = Vec::new();
    let kept = |work: tempfile::TempDir| {
        if keep_on_failure {
            format!("\n--- working directory kept: {}", work.keep().display())
        } else {
            String::new()
        }
    };

    for ex in &examples {
        let t0 = Instant::now();
        let log = logs.path().join(format!("block-{}.txt", ex.line));
        let (ok, status, output) = run_block(&ex.script, work.path(), &path_env, &log);
        eprintln!(
            "{name} line {}: {:.1} s ({})",
            ex.line,
            t0.elapsed().as_secs_f64(),
            ex.script.lines().next().unwrap_or("")
        );
        if show {
            println!("--- {name} line {} ---\n{output}", ex.line);
        }
        if !ok {
            return Err(format!(
                "{name} line {}: the example failed ({status}):\n{}\n\
                 --- its output (stdout and stderr), last 40 lines ---\n{}{}",
                ex.line,
                ex.script,
                tail(&output, 40),
                kept(work)
            ));
        }
        if let Some((shown_line, shown)) = &ex.shown {
            let real: Vec<&str> = output.lines().collect();
            match match_lines(shown, &real) {
                Ok(matched) => {
                    for (k, m) in matched.iter().enumerate() {
                        let Some(r) = m else { continue };
                        let new = if shown[k].contains("...") {
                            let nums = matched_numbers(&shown[k], real[*r]).unwrap_or_default();
                            with_numbers(&shown[k], &nums)
                        } else {
                            real[*r].trim_end().to_string()
                        };
                        if shown[k].trim_end() != new {
                            refresh.push((shown_line + 1 + k, shown[k].clone(), new));
                        }
                    }
                }
                Err(k) => {
                    let at = shown
                        .get(k)
                        .map(|s| format!("line {} (`{s}`)", shown_line + 1 + k))
                        .unwrap_or_else(|| "its end (the real output has more lines)".into());
                    return Err(format!(
                        "{name} line {shown_line}: the output shown for the example at line {} \
                     does not match what it printed, from {name} {at} on \
                     (numbers may differ, `...` elides):\n--- real output ---\n{output}{}",
                        ex.line,
                        kept(work)
                    ));
                }
            }
        }
    }
    eprintln!(
        "{} examples of {name} in {:.1} s",
        examples.len(),
        t_all.elapsed().as_secs_f64()
    );
    Ok((examples.len(), refresh))
}

/// Replaces shown output lines of `path` by the real ones (README_TEST_UPDATE=1).
fn apply_refresh(path: &Path, refresh: &[Refresh]) -> Result<(), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for (n, old, new) in refresh {
        match lines.get_mut(n - 1) {
            Some(l) if l == old => *l = new.clone(),
            _ => {
                return Err(format!(
                    "{} line {n} changed meanwhile: not updated",
                    path.display()
                ))
            }
        }
    }
    let mut out = lines.join("\n");
    if text.ends_with('\n') {
        out.push('\n');
    }
    std::fs::write(path, out).map_err(|e| format!("{}: {e}", path.display()))
}

#[test]
fn readme_examples_run_and_print_what_the_readme_shows() {
    let readme_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md");
    let readme = std::fs::read_to_string(&readme_path).expect("read README.md");
    let (n, refresh) = run_examples(&readme, "README.md", true).unwrap_or_else(|e| panic!("{e}"));
    for (line, old, new) in &refresh {
        eprintln!("README.md line {line}: figures differ\n  shown: {old}\n  real:  {new}");
    }
    if std::env::var_os("README_TEST_UPDATE").is_some() {
        apply_refresh(&readme_path, &refresh).unwrap_or_else(|e| panic!("{e}"));
        eprintln!(
            "README.md: {} output line(s) refreshed from the real runs",
            refresh.len()
        );
    }
    assert!(
        n >= 10,
        "README.md has only {n} run blocks: the user's guide should be runnable"
    );
}

#[test]
fn a_failing_or_stale_example_is_reported_with_its_line_and_output() {
    let ok = "<!-- readme-test: run -->\n```sh\nodocal --version\n```\n\
              <!-- readme-test: output -->\n```text\nodocal 0.1.0\n```\n";
    assert_eq!(run_examples(ok, "t.md", false), Ok((1, vec![])));
    let figures = "<!-- readme-test: run -->\n```sh\necho x 1.5\n```\n\
                   <!-- readme-test: output -->\n```text\nx 2.0\n```\n";
    assert_eq!(
        run_examples(figures, "t.md", false),
        Ok((1, vec![(7, "x 2.0".into(), "x 1.5".into())]))
    );

    let failing = "intro\n\n<!-- readme-test: run -->\n```sh\necho made > a.txt\n```\n\
                   <!-- readme-test: run -->\n```sh\ncat a.txt\nodocal track missing.avi --camera c.json --out t.csv\necho never\n```\n";
    let e = run_examples(failing, "t.md", false).expect_err("the second block fails");
    assert!(e.starts_with("t.md line 8: the example failed"), "{e}");
    assert!(e.contains("made\nodocal: error: "), "{e}");
    let output = e.split("last 40 lines ---").nth(1).unwrap_or("");
    assert!(
        !output.contains("never"),
        "bash -e stops at the failing command: {e}"
    );

    let stale = "<!-- readme-test: run -->\n```sh\necho a 1; echo b 2\n```\n\
                 <!-- readme-test: output -->\n```text\na 5\nc 2\n```\n";
    let e = run_examples(stale, "t.md", false).expect_err("the output differs");
    assert!(
        e.starts_with("t.md line 6: the output shown for the example at line 2 does not match"),
        "{e}"
    );
    assert!(e.contains("from t.md line 8 (`c 2`) on"), "{e}");
    assert!(e.contains("--- real output ---\na 1\nb 2"), "{e}");
}

#[test]
fn shown_output_matching_rules() {
    let m = |shown: &str, real: &str| line_matches(shown, real);
    assert!(m("  fx =    913.959 px ± 0.553", "  fx =  1914.5 px ± 0.6"));
    assert!(m("k1 = -0.10968", "k1 = 0.2"));
    assert!(m("perceptron 18-8-2", "perceptron 18-11-2"));
    assert!(m(
        "worst views: view_10.png 0.082 px, ...",
        "worst views: view_3.png 1 px, a, b"
    ));
    assert!(m("MSE 1e-4 m²", "MSE 2.5E+3 m²"));
    assert!(!m("wrote camera.json", "wrote camera.yaml"));
    assert!(!m("0.5 px", "px"));
    assert!(!m("a b", "ab"));
    assert!(!m("x 1 m", "x 1 m extra"));
    let shown = "best 18-12-2 4.39 % ... (48 % of raw)";
    let nums = matched_numbers(shown, "best 18-8-2 4.4 % wins (50 % of raw)").expect("match");
    assert_eq!(nums, ["18", "-8", "-2", "4.4", "50"]);
    assert_eq!(
        with_numbers(shown, &nums),
        "best 18-8-2 4.4 % ... (50 % of raw)"
    );

    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert_eq!(
        match_lines(&s(&["a 1", "b"]), &["a 2", "b"]),
        Ok(vec![Some(0), Some(1)])
    );
    assert_eq!(
        match_lines(&s(&["a", "..."]), &["a", "b", "c"]),
        Ok(vec![Some(0), None])
    );
    assert_eq!(
        match_lines(&s(&["...", "c"]), &["a", "b", "c"]),
        Ok(vec![None, Some(2)])
    );
    assert_eq!(
        match_lines(&s(&["a", "...", "b"]), &["a", "b"]),
        Ok(vec![Some(0), None, Some(1)])
    );
    assert_eq!(match_lines(&s(&["a", "c"]), &["a", "b", "c"]), Err(1));
    assert_eq!(match_lines(&s(&["a"]), &["a", "b"]), Err(1));
    assert_eq!(match_lines(&s(&["b", "a"]), &["a", "b"]), Err(0));

    let md = "x\n<!-- readme-test: run -->\n```sh\necho 1\n```\n<!-- readme-test: output -->\n```text\n1\n```\n```text\nfree\n```\n";
    let ex = examples(&parse_blocks(md, "t.md").expect("parse"), "t.md").expect("examples");
    assert_eq!(ex.len(), 1);
    assert_eq!(ex[0].line, 3);
    assert_eq!(ex[0].shown, Some((7, vec!["1".to_string()])));
    assert!(examples(
        &parse_blocks("```sh\nls\n```\n", "t.md").expect("parse"),
        "t.md"
    )
    .is_err());
    assert!(parse_blocks("<!-- readme-test: run -->\ntext\n```sh\nls\n```\n", "t.md").is_err());
    let inline = "text with ```` ```sh ```` inline\n```` ```sh ```` at a line start\n";
    assert!(parse_blocks(inline, "t.md").expect("parse").is_empty());
    assert!(parse_blocks("<!-- readme-test: runn -->\n```sh\nls\n```\n", "t.md").is_err());
}
