//! The README's layout table (`## Layout`) against the workspace: every workspace member
//! directory (the `[workspace] members` of Cargo.toml, globs expanded) and every file of
//! `configs/` is listed, exactly or by a glob row (`stages/*`), and every path a row names
//! exists (a glob row matches at least one path).

use std::fs;
use std::path::Path;

use pino_mbd_tests::workspace_root;

/// The heading of the README section holding the table.
const SECTION: &str = "## Layout";

/// The paths of the layout table in `readme`: every backquoted name of each row's first
/// cell (`` `configs/quarter-car.yaml`, `configs/bridge.yaml` `` gives two), without a
/// trailing `/`. An error when the section or its table is missing.
fn layout_paths(readme: &str) -> Result<Vec<String>, String> {
    let start = readme
        .lines()
        .position(|l| l.trim() == SECTION)
        .ok_or_else(|| format!("README.md: no `{SECTION}` section"))?;
    let rows = readme
        .lines()
        .skip(start + 1)
        .take_while(|l| !l.starts_with("## "))
        .filter(|l| l.trim_start().starts_with('|'))
        .skip(2); // the header row and its `|---|` rule
    let mut paths = Vec::new();
    for row in rows {
        let cell = row.trim_start().trim_start_matches('|');
        let first = cell.split('|').next().unwrap_or_default();
        let names: Vec<&str> = first.split('`').skip(1).step_by(2).collect();
        if names.is_empty() {
            return Err(format!("README.md layout row names no `path`: {row}"));
        }
        paths.extend(names.iter().map(|n| n.trim_end_matches('/').to_string()));
    }
    if paths.is_empty() {
        return Err(format!(
            "README.md: the `{SECTION}` section holds no table rows"
        ));
    }
    Ok(paths)
}

/// Whether `path` matches `pattern`, segment by segment; `*` in a segment matches any run of
/// characters but `/`.
fn glob_match(pattern: &str, path: &str) -> bool {
    let (p, s): (Vec<&str>, Vec<&str>) = (pattern.split('/').collect(), path.split('/').collect());
    p.len() == s.len() && p.iter().zip(&s).all(|(p, s)| segment_match(p, s))
}

fn segment_match(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((head, rest)) => {
            name.starts_with(head)
                && (head.len()..=name.len())
                    .any(|i| name.is_char_boundary(i) && segment_match(rest, &name[i..]))
        }
    }
}

/// Every path under `root` (relative, `/`-separated) matching `pattern`.
fn expand(root: &Path, pattern: &str) -> Vec<String> {
    let mut found = vec![String::new()];
    for seg in pattern.split('/') {
        let mut next = Vec::new();
        for dir in &found {
            let join = |name: &str| {
                if dir.is_empty() {
                    name.to_string()
                } else {
                    format!("{dir}/{name}")
                }
            };
            if !seg.contains('*') {
                if root.join(join(seg)).exists() {
                    next.push(join(seg));
                }
                continue;
            }
            let Ok(entries) = fs::read_dir(root.join(dir)) else {
                continue;
            };
            for e in entries.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if segment_match(seg, &name) {
                    next.push(join(&name));
                }
            }
        }
        found = next;
    }
    found.sort();
    found
}

/// The `members` of the `[workspace]` table of a Cargo.toml text (a one- or multi-line array
/// of strings).
fn workspace_members(manifest: &str) -> Result<Vec<String>, String> {
    let ws = manifest
        .split_once("[workspace]")
        .ok_or("Cargo.toml: no [workspace] table")?
        .1;
    let ws = ws.split("\n[").next().unwrap_or_default();
    let array = ws
        .split_once("members")
        .and_then(|(_, rest)| rest.split_once('['))
        .and_then(|(_, rest)| rest.split_once(']'))
        .ok_or("Cargo.toml: no `members = [...]` in [workspace]")?
        .0;
    Ok(array
        .split('"')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect())
}

/// What the table at `listed` gets wrong about the workspace at `root`: a member directory or
/// a `configs/` file no row covers, a row naming nothing that exists. Empty when it is true.
fn layout_problems(root: &Path, listed: &[String]) -> Vec<String> {
    let manifest = fs::read_to_string(root.join("Cargo.toml")).expect("workspace Cargo.toml");
    let mut must = Vec::new();
    for member in workspace_members(&manifest).expect("workspace members") {
        let dirs = expand(root, &member);
        let packages = dirs
            .iter()
            .filter(|d| root.join(d).join("Cargo.toml").is_file());
        must.extend(packages.map(|d| (d.clone(), "workspace member")));
    }
    let configs = fs::read_dir(root.join("configs")).expect("configs/");
    for e in configs.flatten().filter(|e| e.path().is_file()) {
        let name = e.file_name().to_string_lossy().into_owned();
        must.push((format!("configs/{name}"), "file of configs/"));
    }
    let mut problems = Vec::new();
    for (path, what) in &must {
        if !listed.iter().any(|l| glob_match(l, path)) {
            problems.push(format!(
                "{what} `{path}` is not in the README's layout table"
            ));
        }
    }
    for l in listed {
        if expand(root, l).is_empty() {
            problems.push(format!(
                "the README's layout table lists `{l}`, which does not exist"
            ));
        }
    }
    problems
}

fn readme() -> String {
    fs::read_to_string(workspace_root().join("README.md")).expect("README.md")
}

#[test]
fn the_readme_layout_table_matches_the_workspace() {
    let listed = layout_paths(&readme()).unwrap_or_else(|e| panic!("{e}"));
    let problems = layout_problems(&workspace_root(), &listed);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The README with every layout row naming `path` (or `path/`) removed.
fn without_row(readme: &str, path: &str) -> String {
    let names = [format!("`{path}`"), format!("`{path}/`")];
    let names_it = |l: &str| l.starts_with('|') && names.iter().any(|n| l.contains(n.as_str()));
    let lines = readme.lines().filter(|l| !names_it(l));
    lines.collect::<Vec<_>>().join("\n")
}

/// The README with one more layout row, naming `path`.
fn with_row(readme: &str, path: &str) -> String {
    readme.replacen(
        "|---|---|\n",
        &format!("|---|---|\n| `{path}` | an extra row |\n"),
        1,
    )
}

#[test]
fn a_table_missing_a_member_or_a_config_fails() {
    let root = workspace_root();
    let text = readme();
    for path in [
        "crates/conformal",
        "crates/studies",
        "configs/long.yaml",
        "tests",
    ] {
        let broken = without_row(&text, path);
        assert_ne!(broken, text, "README.md has no row `{path}` to remove");
        let problems = layout_problems(&root, &layout_paths(&broken).unwrap());
        assert!(
            problems
                .iter()
                .any(|p| p.contains(&format!("`{path}` is not"))),
            "without `{path}`: {problems:?}"
        );
    }
}

#[test]
fn a_table_listing_what_does_not_exist_fails() {
    let root = workspace_root();
    for path in ["configs/rates-*.yaml", "crates/nowhere", "docs/none.md"] {
        let broken = with_row(&readme(), path);
        let problems = layout_problems(&root, &layout_paths(&broken).unwrap());
        assert_eq!(
            problems,
            [format!(
                "the README's layout table lists `{path}`, which does not exist"
            )],
            "with `{path}`"
        );
    }
}

#[test]
fn a_glob_row_covers_its_matches_only() {
    assert!(glob_match("stages/*", "stages/train"));
    assert!(glob_match("configs/*.yaml", "configs/long.yaml"));
    assert!(!glob_match("configs/*.yaml", "configs/long.yml"));
    assert!(!glob_match("stages/*", "stages/train/src"));
    assert!(!glob_match("crates/pino-*", "crates/conformal"));
    assert!(glob_match("a*b*c", "aXbYbZc"));
}

#[test]
fn a_readme_without_the_table_is_an_error() {
    assert!(layout_paths("# x\n\n## Other\n").is_err());
    assert!(layout_paths("## Layout\n\nno table\n").is_err());
    let bad = "## Layout\n\n| path | what |\n|---|---|\n| no path here | x |\n";
    assert!(layout_paths(bad).unwrap_err().contains("no `path`"));
}

#[test]
fn members_are_read_from_one_or_many_lines() {
    let one = "[workspace]\nresolver = \"2\"\nmembers = [\"crates/*\", \"tests\"]\n";
    assert_eq!(workspace_members(one).unwrap(), ["crates/*", "tests"]);
    let many = "[workspace]\nmembers = [\n  \"a\",\n  \"b/*\",\n]\n[workspace.package]\n";
    assert_eq!(workspace_members(many).unwrap(), ["a", "b/*"]);
    assert!(workspace_members("[package]\nname = \"x\"\n").is_err());
}
