//! The explorer page's logic under Node.js's own test runner: `node --test` runs every
//! `tests/browser/unit/*.test.mjs`, which import the page's pure modules (state, formatting,
//! verdicts, the API wrapper) straight from `crates/explore/assets`. Needs Node.js (20+) on
//! PATH (no npm package); fails, never skips, without it.

use pino_mbd_tests::{output_text, workspace_root};
use std::process::Command;

#[test]
fn the_pages_logic_passes_its_node_unit_tests() {
    let dir = workspace_root().join("tests/browser/unit");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.to_string_lossy().ends_with(".test.mjs"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no *.test.mjs in {}", dir.display());
    let o = Command::new("node")
        .current_dir(workspace_root())
        .args(["--test", "--test-reporter=tap"])
        .args(&files)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "`node` (Node.js 20 or newer, from PATH) does not run: {e}; install it \
                 (apt-get install nodejs, or run `scripts/test`, which installs what is missing)"
            )
        });
    let text = output_text(&o);
    assert!(o.status.success(), "node --test failed:\n{text}");
    let count = |key: &str| -> usize {
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("# {key} ")))
            .and_then(|n| n.trim().parse().ok())
            .unwrap_or_else(|| panic!("no `# {key}` line in node's report:\n{text}"))
    };
    assert_eq!(count("fail"), 0, "{text}");
    assert!(count("pass") >= 10, "too few unit tests ran:\n{text}");
    println!(
        "node --test: {} unit tests of the page passed",
        count("pass")
    );
}
