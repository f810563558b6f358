//! The relative links of README.md, BENCHMARKS.md and docs/*.md: each names a file or folder
//! of the repository, and an anchor into a Markdown file names one of its headings (GitHub's
//! rule: lower case, punctuation dropped, spaces as `-`, `-1`, `-2` for repeats).

use std::fs;
use std::path::{Path, PathBuf};

use pino_mbd_tests::workspace_root;

/// The link targets `](target)` of a Markdown text outside fenced code blocks, with their
/// line numbers.
fn link_targets(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        for part in line.split("](").skip(1) {
            if let Some(end) = part.find(')') {
                out.push((i + 1, part[..end].trim().to_string()));
            }
        }
    }
    out
}

/// GitHub's anchor of a heading text.
fn slug(heading: &str) -> String {
    let kept = heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .collect::<String>();
    kept.replace(' ', "-")
}

/// The anchors of every heading of a Markdown text (outside fenced code blocks).
fn anchors(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        let Some(heading) = line.strip_prefix('#') else {
            continue;
        };
        if fenced {
            continue;
        }
        let base = slug(heading.trim_start_matches('#'));
        let repeats =
            |a: &&String| a.as_str() == base || a.strip_prefix(&base).is_some_and(is_repeat_suffix);
        let seen = out.iter().filter(repeats).count();
        out.push(if seen == 0 {
            base
        } else {
            format!("{base}-{seen}")
        });
    }
    out
}

fn is_repeat_suffix(rest: &str) -> bool {
    rest.strip_prefix('-')
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// What is wrong with the relative links of the Markdown file `file` (a path under `root`).
fn broken_links(root: &Path, file: &str) -> Vec<String> {
    let text = fs::read_to_string(root.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
    let dir = Path::new(file).parent().unwrap_or(Path::new(""));
    let mut problems = Vec::new();
    for (line, target) in link_targets(&text) {
        if target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (path, anchor) = target.split_once('#').unwrap_or((&target, ""));
        let resolved: PathBuf = if path.is_empty() {
            root.join(file)
        } else {
            root.join(dir).join(path)
        };
        if !resolved.exists() {
            problems.push(format!("{file}:{line}: `{target}`: no such file"));
            continue;
        }
        let is_md = resolved.extension().is_some_and(|e| e == "md");
        if anchor.is_empty() || !is_md {
            continue;
        }
        let heads = anchors(&fs::read_to_string(&resolved).expect("linked Markdown file"));
        if !heads.iter().any(|a| a == anchor) {
            problems.push(format!("{file}:{line}: `{target}`: no heading `#{anchor}`"));
        }
    }
    problems
}

/// The Markdown files a user reads: README.md, BENCHMARKS.md, CHANGELOG.md and docs/*.md.
fn user_docs(root: &Path) -> Vec<String> {
    let mut files = vec![
        "README.md".to_string(),
        "BENCHMARKS.md".into(),
        "CHANGELOG.md".into(),
    ];
    for e in fs::read_dir(root.join("docs")).expect("docs/").flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".md") {
            files.push(format!("docs/{name}"));
        }
    }
    files.sort();
    files
}

#[test]
fn every_relative_link_of_the_docs_resolves() {
    let root = workspace_root();
    let problems: Vec<String> = user_docs(&root)
        .iter()
        .flat_map(|f| broken_links(&root, f))
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_link_to_a_missing_file_or_heading_is_found() {
    let dir = tempfile::tempdir().unwrap();
    fs::create_dir(dir.path().join("docs")).unwrap();
    let page = "# A page\n\n## Two words, here\n\n## Two words, here\n";
    fs::write(dir.path().join("docs/a.md"), page).unwrap();
    let readme = "See [a](docs/a.md), [b](docs/a.md#two-words-here), \
                  [c](docs/a.md#two-words-here-1) and [web](https://example.org).\n\
                  ```\n[not a link](nowhere.md)\n```\n\
                  Broken: [d](docs/b.md) [e](docs/a.md#three) [f](#nothing).\n";
    fs::write(dir.path().join("README.md"), readme).unwrap();
    assert_eq!(
        broken_links(dir.path(), "README.md"),
        [
            "README.md:5: `docs/b.md`: no such file",
            "README.md:5: `docs/a.md#three`: no heading `#three`",
            "README.md:5: `#nothing`: no heading `#nothing`",
        ]
    );
}

#[test]
fn anchors_follow_github() {
    let text = "# pino-mbd\n## The wheel-load reduction rate, third look\n## `predict`: one pass\n\
                ## Layout\n## Layout\n```\n# not a heading\n```\n";
    assert_eq!(
        anchors(text),
        [
            "pino-mbd",
            "the-wheel-load-reduction-rate-third-look",
            "predict-one-pass",
            "layout",
            "layout-1",
        ]
    );
}
