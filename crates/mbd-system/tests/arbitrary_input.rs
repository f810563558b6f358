//! Never a panic on arbitrary input: thousands of mutated versions of the three real
//! descriptions (`systems/*.yaml`) and of random text go through [`mbd_system::load_str`]; each
//! call must return (a system or diagnostics) without panicking, every diagnostic line must
//! have the `file:line:col: message` form with a line inside the text, and every system that
//! compiles must instantiate at its nominal values and at the corners of its sampling box
//! without panicking (an `Err` there is allowed: a mutated range may put a mass below zero).
//!
//! The mutator is deterministic (a SplitMix64 stream from fixed seeds), so a failure is
//! reproduced by rerunning the test; the failing text is printed with the case number.
//! Mutations: byte flips (the bytes read back as lossy UTF-8), line deletions, duplications,
//! swaps and re-indentation, token swaps and replacements (tokens of the three files and a
//! dictionary of YAML indicators, keywords and extreme numbers: `.nan`, `1e309`, `-0`, 2^64),
//! truncations, random UTF-8 (control characters, BOM, line separators, astral characters),
//! deep nesting of YAML collections and of expressions, long sums, parameter overrides with
//! extreme values; and plain random texts.

use mbd_system::{load_str, Override, SampledError};
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};

const FILES: [&str; 3] = ["vtcd.yaml", "quarter-car.yaml", "bridge.yaml"];
/// Mutated cases per description.
const CASES_PER_FILE: usize = 4000;
/// Random texts.
const RANDOM_TEXTS: usize = 500;

fn description(file: &str) -> String {
    let path = format!("{}/../../systems/{file}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// SplitMix64: a tiny, well-mixed deterministic stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Replacement tokens beyond those of the files: extremes, YAML indicators and keywords.
const DICTIONARY: &[&str] = &[
    ".nan",
    ".inf",
    "-.inf",
    "NaN",
    "inf",
    "1e308",
    "1e309",
    "-1e309",
    "1e-320",
    "0",
    "-0",
    "-1",
    "0.5",
    "4294967296",
    "18446744073709551616",
    "1e7",
    "10000001",
    "\"1e999\"",
    "\"0/0\"",
    "\"-1/0\"",
    "\"ln(0)\"",
    "\"sqrt(-1)\"",
    "\"2^1024\"",
    "~",
    "null",
    "true",
    "[]",
    "{}",
    "\"\"",
    "''",
    "&a",
    "*a",
    "!tag",
    "---",
    "...",
    "%YAML 1.2",
    "? ",
    ": ",
    "- ",
    "|",
    ">-",
    "#",
    ",",
    "[",
    "]",
    "{",
    "}",
    "ground",
    "pitch",
    "z",
    "harmonic",
    "table",
    "hertz",
    "spring_damper",
    "rigid",
    "refuse",
    "pi",
    "sqrt",
    "min(",
    "max(1,",
];

/// Random characters: ASCII, YAML indicators, controls, BOM, separators, astral planes.
fn random_char(rng: &mut Rng) -> char {
    match rng.below(6) {
        0 => (b' ' + rng.below(95) as u8) as char,
        1 => *rng.pick(&[
            ':', '-', '?', '[', ']', '{', '}', ',', '#', '&', '*', '!', '|', '>', '\'', '"', '%',
            '@', '`', '\n', ' ', '\t',
        ]),
        2 => *rng.pick(&[
            '\0', '\r', '\u{1b}', '\u{7f}', '\u{85}', '\u{a0}', '\u{feff}', '\u{2028}', '\u{2029}',
            '\u{fffd}',
        ]),
        3 => *rng.pick(&['é', 'ß', '中', 'Ω', '🚆', '\u{10ffff}', '\u{1d400}']),
        _ => loop {
            if let Some(c) = char::from_u32(rng.next() as u32 % 0x11_0000) {
                break c;
            }
        },
    }
}

/// Tokens: runs of name/number characters, or single other characters.
fn tokens(text: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in text.char_indices() {
        let word = c.is_alphanumeric() || "_.+-".contains(c);
        match (word, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push(&text[s..i]);
                start = None;
            }
            _ => {}
        }
        if !word && !c.is_whitespace() {
            out.push(&text[i..i + c.len_utf8()]);
        }
    }
    if let Some(s) = start {
        out.push(&text[s..]);
    }
    out
}

/// Byte ranges of the tokens of `text`.
fn token_spans(text: &str) -> Vec<(usize, usize)> {
    let base = text.as_ptr() as usize;
    tokens(text)
        .into_iter()
        .map(|t| {
            let s = t.as_ptr() as usize - base;
            (s, s + t.len())
        })
        .collect()
}

fn char_boundary(text: &str, rng: &mut Rng) -> usize {
    let mut i = rng.below(text.len() + 1);
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn nested(rng: &mut Rng) -> String {
    let depth = 1 + rng.below(200);
    match rng.below(7) {
        0 => "[".repeat(depth) + &"]".repeat(depth),
        1 => "{a: ".repeat(depth) + "1" + &"}".repeat(depth),
        2 => format!("\"{}1{}\"", "(".repeat(depth), ")".repeat(depth)),
        3 => format!("\"{}1\"", "-".repeat(depth)),
        4 => format!("\"{}2\"", "2^".repeat(depth)),
        5 => format!("\"{}1\"", "1+".repeat(depth * 20)),
        _ => {
            // Block-style nesting, one level per line.
            let mut s = String::from("\n");
            for d in 0..depth {
                s += &" ".repeat(d);
                s += "a:\n";
            }
            s
        }
    }
}

/// One random mutation of `text`.
fn mutate(text: &str, rng: &mut Rng, dictionary: &[&str]) -> String {
    let lines: Vec<&str> = text.lines().collect();
    match rng.below(12) {
        // Byte flips.
        0 => {
            let mut bytes = text.as_bytes().to_vec();
            for _ in 0..1 + rng.below(4) {
                if bytes.is_empty() {
                    break;
                }
                let i = rng.below(bytes.len());
                bytes[i] = if rng.below(2) == 0 {
                    bytes[i] ^ (1 << rng.below(8))
                } else {
                    rng.next() as u8
                };
            }
            String::from_utf8_lossy(&bytes).into_owned()
        }
        // Line deletion, duplication, swap, re-indentation.
        1..=3 if !lines.is_empty() => {
            let mut lines: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            let i = rng.below(lines.len());
            match rng.below(4) {
                0 => {
                    lines.remove(i);
                }
                1 => lines.insert(i, lines[i].clone()),
                2 => {
                    let j = rng.below(lines.len());
                    lines.swap(i, j);
                }
                _ => {
                    if rng.below(2) == 0 {
                        lines[i].insert_str(0, &" ".repeat(1 + rng.below(3)));
                    } else {
                        let n = lines[i].len() - lines[i].trim_start_matches(' ').len();
                        lines[i].drain(..n.min(1 + rng.below(3)));
                    }
                }
            }
            lines.join("\n") + "\n"
        }
        // Token swap or replacement.
        4..=6 => {
            let spans = token_spans(text);
            if spans.is_empty() {
                return text.to_owned();
            }
            let (s, e) = *rng.pick(&spans);
            if rng.below(3) == 0 {
                let (s2, e2) = *rng.pick(&spans);
                let (a, b) = if s <= s2 {
                    ((s, e), (s2, e2))
                } else {
                    ((s2, e2), (s, e))
                };
                if a.1 > b.0 {
                    return text.to_owned();
                }
                format!(
                    "{}{}{}{}{}",
                    &text[..a.0],
                    &text[b.0..b.1],
                    &text[a.1..b.0],
                    &text[a.0..a.1],
                    &text[b.1..]
                )
            } else {
                format!("{}{}{}", &text[..s], rng.pick(dictionary), &text[e..])
            }
        }
        // Truncation.
        7 => text[..char_boundary(text, rng)].to_owned(),
        // Random UTF-8 inserted.
        8 => {
            let i = char_boundary(text, rng);
            let noise: String = (0..1 + rng.below(12)).map(|_| random_char(rng)).collect();
            format!("{}{noise}{}", &text[..i], &text[i..])
        }
        // Deep nesting, in place of a token or inserted.
        9 => {
            let spans = token_spans(text);
            let deep = nested(rng);
            match spans.is_empty() {
                true => deep,
                false => {
                    let (s, e) = *rng.pick(&spans);
                    format!("{}{deep}{}", &text[..s], &text[e..])
                }
            }
        }
        // A number replaced by an extreme one.
        10 => {
            let spans: Vec<(usize, usize)> = token_spans(text)
                .into_iter()
                .filter(|&(s, e)| text[s..e].starts_with(|c: char| c.is_ascii_digit()))
                .collect();
            if spans.is_empty() {
                return text.to_owned();
            }
            let (s, e) = *rng.pick(&spans);
            format!(
                "{}{}{}",
                &text[..s],
                rng.pick(&DICTIONARY[..22]),
                &text[e..]
            )
        }
        // A section emptied, or the whole text replaced by next to nothing.
        _ => match rng.below(4) {
            0 => String::new(),
            1 => " \n\t\n".to_owned(),
            2 => "# only a comment\n".to_owned(),
            _ => lines
                .iter()
                .filter(|l| !l.starts_with("  "))
                .copied()
                .collect::<Vec<_>>()
                .join("\n"),
        },
    }
}

/// Overrides for a run: a parameter of the text (or an unknown one) given an extreme value or
/// range.
fn overrides(text: &str, rng: &mut Rng) -> BTreeMap<String, Override> {
    let mut out = BTreeMap::new();
    if rng.below(4) != 0 {
        return out;
    }
    let names: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("  ")?.split(':').next())
        .filter(|n| !n.starts_with(' '))
        .collect();
    let name = if names.is_empty() || rng.below(8) == 0 {
        "nope".to_owned()
    } else {
        rng.pick(&names).trim().to_owned()
    };
    let extremes = [0.0, -0.0, -1.0, 1e308, f64::NAN, f64::INFINITY, 1e7, 0.5];
    let o = if rng.below(2) == 0 {
        Override::Value(*rng.pick(&extremes))
    } else {
        Override::Range([*rng.pick(&extremes), *rng.pick(&extremes)])
    };
    out.insert(name, o);
    out
}

#[derive(Default)]
struct Tally {
    ok: usize,
    err: usize,
    beyond_syntax: usize,
    instantiated: usize,
    panics: Vec<String>,
}

/// Runs one text through the whole front end; records panics and malformed diagnostics.
fn check(case: &str, text: &str, values: &BTreeMap<String, Override>, tally: &mut Tally) {
    let result = catch_unwind(AssertUnwindSafe(|| load_str(text, "fuzz.yaml", values)));
    let system = match result {
        Err(_) => {
            tally.panics.push(format!(
                "{case}: load_str panicked on\n{text:?}\n{values:?}"
            ));
            return;
        }
        Ok(Err(diag)) => {
            tally.err += 1;
            let shown = diag.to_string();
            assert!(!shown.is_empty(), "{case}: an error without a message");
            if !shown.contains("not valid YAML") {
                tally.beyond_syntax += 1;
            }
            // YAML breaks lines at `\n`, `\r\n` and a lone `\r`; the end of the input may be
            // reported on the line after the last.
            let max_line = 2 + text.replace("\r\n", "\n").matches(['\n', '\r']).count();
            for line in shown.lines() {
                let rest = line
                    .strip_prefix("fuzz.yaml:")
                    .unwrap_or_else(|| panic!("{case}: `{line}` does not name the file"));
                let mut parts = rest.splitn(3, ':');
                let l: usize = parts.next().and_then(|p| p.parse().ok()).unwrap_or(0);
                let c: usize = parts.next().and_then(|p| p.parse().ok()).unwrap_or(0);
                assert!(
                    (1..=max_line).contains(&l) && c >= 1,
                    "{case}: `{line}` has no line in 1..={max_line} and column: {text:?}"
                );
                assert!(
                    parts.next().is_some_and(|m| m.len() > 2),
                    "{case}: `{line}` has no message"
                );
            }
            return;
        }
        Ok(Ok(system)) => system,
    };
    tally.ok += 1;
    let nominal = system.nominal();
    let ranges = system.ranges();
    let corner = |end: usize| {
        let values: Vec<f64> = ranges.iter().map(|r| r[end]).collect();
        system
            .sampled_values(values)
            .expect("one range per sampled parameter")
    };
    let (low, high) = (corner(0), corner(1));
    for (which, sample) in [("nominal", &nominal), ("low", &low), ("high", &high)] {
        match catch_unwind(AssertUnwindSafe(|| system.instantiate(sample))) {
            Err(_) => tally.panics.push(format!(
                "{case}: instantiate at the {which} values panicked on\n{text:?}\n{values:?}"
            )),
            Ok(Ok(_)) => tally.instantiated += 1,
            Ok(Err(_)) => {}
        }
    }
}

#[test]
fn the_real_descriptions_compile_and_instantiate() {
    for file in FILES {
        let text = description(file);
        let system = load_str(&text, file, &BTreeMap::new()).unwrap_or_else(|d| panic!("{d}"));
        let nominal = system.nominal();
        system
            .instantiate(&nominal)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        // One value short or one too many: refused, naming the parameters in their order.
        let nominal = nominal.as_slice();
        let short = &nominal[..nominal.len() - 1];
        let long: Vec<f64> = nominal.iter().copied().chain([1.0]).collect();
        for wrong in [short, &long[..]] {
            let e = system.sampled_values(wrong).unwrap_err();
            assert!(
                matches!(e, SampledError::Count { got, .. } if got == wrong.len()),
                "{file}: {e}"
            );
            let names = system.sampled_names().join(", ");
            assert!(e.to_string().contains(&names), "{file}: {e}");
        }
    }
}

#[test]
fn mutated_descriptions_never_panic() {
    let texts: Vec<String> = FILES.iter().map(|f| description(f)).collect();
    let mut dictionary: Vec<&str> = DICTIONARY.to_vec();
    for t in &texts {
        dictionary.extend(tokens(t));
    }
    let mut tally = Tally::default();
    for (f, base) in texts.iter().enumerate() {
        let mut rng = Rng(0x5EED_0000 + f as u64);
        for case in 0..CASES_PER_FILE {
            let mut text = base.clone();
            for _ in 0..1 + rng.below(4) {
                text = mutate(&text, &mut rng, &dictionary);
            }
            let values = overrides(&text, &mut rng);
            check(
                &format!("{} case {case}", FILES[f]),
                &text,
                &values,
                &mut tally,
            );
        }
    }
    assert!(
        tally.panics.is_empty(),
        "{} panics, the first:\n{}",
        tally.panics.len(),
        tally.panics[0]
    );
    println!(
        "{} compiled ({} instantiations), {} refused ({} beyond the YAML syntax)",
        tally.ok, tally.instantiated, tally.err, tally.beyond_syntax
    );
    // The mutations are meaningful: some still compile, most are refused, and refusals reach
    // past the YAML syntax into the checks of the description.
    let total = FILES.len() * CASES_PER_FILE;
    assert_eq!(tally.ok + tally.err, total);
    assert!(
        tally.ok >= total / 20,
        "only {} of {total} compiled",
        tally.ok
    );
    assert!(
        tally.err >= total / 2,
        "only {} of {total} refused",
        tally.err
    );
    assert!(
        tally.beyond_syntax >= tally.err / 3,
        "only {} of {} refusals beyond the YAML syntax",
        tally.beyond_syntax,
        tally.err
    );
    assert!(tally.instantiated > 0);
}

#[test]
fn random_texts_never_panic() {
    let mut rng = Rng(0x000A_11CE);
    let mut tally = Tally::default();
    for case in 0..RANDOM_TEXTS {
        let len = rng.below(400);
        let text: String = (0..len).map(|_| random_char(&mut rng)).collect();
        check(
            &format!("random {case}"),
            &text,
            &BTreeMap::new(),
            &mut tally,
        );
    }
    assert!(
        tally.panics.is_empty(),
        "{} panics, the first:\n{}",
        tally.panics.len(),
        tally.panics[0]
    );
    assert_eq!(tally.err + tally.ok, RANDOM_TEXTS);
}

/// Nesting at and beyond the limits of the YAML reader and of the expression parser is refused
/// with a message, not a stack overflow.
#[test]
fn deep_nesting_is_refused_with_a_message() {
    for depth in [63, 64, 65, 1000, 100_000] {
        let text = "[".repeat(depth) + &"]".repeat(depth);
        let err = load_str(&text, "deep.yaml", &BTreeMap::new()).unwrap_err();
        assert!(err.to_string().starts_with("deep.yaml:1:"), "{err}");
        let text = format!(
            "format: 1\nname: x\nparameters:\n  m: {{unit: kg, expr: \"{}1{}\"}}\n",
            "(".repeat(depth),
            ")".repeat(depth)
        );
        let err = load_str(&text, "deep.yaml", &BTreeMap::new()).unwrap_err();
        assert!(err.to_string().contains("deep.yaml:4:"), "{err}");
    }
}

/// Nested aliases that would expand a few lines into 10^9 nodes (the "billion laughs") are
/// refused at the line where the expansion passes the reader's limit, not built.
#[test]
fn exponential_aliases_are_refused() {
    let mut text = String::from(
        "format: 1\nname: laughs\nlol0: &l0 [ha, ha, ha, ha, ha, ha, ha, ha, ha, ha]\n",
    );
    for i in 1..10 {
        let p = format!("*l{}", i - 1);
        text += &format!("lol{i}: &l{i} [{}]\n", vec![p; 10].join(", "));
    }
    let err = load_str(&text, "laughs.yaml", &BTreeMap::new()).unwrap_err();
    let shown = err.to_string();
    assert_eq!(shown.lines().count(), 1, "{shown}");
    assert!(
        shown.starts_with("laughs.yaml:7:") && shown.contains("aliases expanded"),
        "{shown}"
    );
}
