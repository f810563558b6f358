//! A YAML document as a tree of nodes that remember where they were written.
//!
//! The description format needs every error to name its line, so the document is read with
//! the event parser of `saphyr-parser` into [`Node`]s carrying a 1-based line and column.
//! Scalars keep their source text (numbers are interpreted by the consumer: a field may be a
//! number or an expression); mappings keep their keys in file order and refuse a duplicate key
//! (YAML allows it silently, a parameter declared twice is a mistake). Anchors and aliases are
//! supported (an alias is a copy of the anchored node, with the anchor's position); tags are
//! refused, and so are documents nested deeper than [`MAX_DEPTH`] (a fuzzer's favourite) or
//! larger than [`MAX_NODES`] nodes with the aliases expanded (nested aliases grow a short text
//! exponentially: the "billion laughs").
//!
//! A flow collection (`{...}`, `[...]`) left open is reported where it was opened, not where
//! the parser gives up (often a line or two later, on the next key): when the parser fails, a
//! scan of the text for flow brackets (`unclosed_flow`: quoted strings, comments and block
//! scalars skipped) names the bracket never closed, and the parser's own position is kept
//! whenever that bracket is not one the parser had open when it failed.

use saphyr_parser::{Event, Parser, ScalarStyle};
use std::collections::HashMap;
use std::ops::ControlFlow;

/// Deepest nesting of collections accepted.
pub const MAX_DEPTH: usize = 64;

/// Most nodes a document may have, every alias counted as a copy of its anchored node (the
/// vehicle-track description has about 700).
pub const MAX_NODES: usize = 100_000;

/// A position in the source: 1-based line and column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub struct Pos {
    /// Line, from 1.
    pub line: usize,
    /// Column, from 1.
    pub col: usize,
}

impl std::fmt::Display for Pos {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

/// A node of the document.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Where the node starts.
    pub pos: Pos,
    /// Its content.
    pub value: Value,
}

/// Content of a [`Node`].
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A scalar with its text as written; `quoted` when it was a quoted or block string (never
    /// a number, boolean or null).
    Scalar {
        /// The text.
        text: String,
        /// Whether it was written in quotes or as a block scalar.
        quoted: bool,
    },
    /// A sequence.
    Seq(Vec<Node>),
    /// A mapping in file order; keys are scalars (their text).
    Map(Vec<(Key, Node)>),
}

/// A mapping key: its text and position.
#[derive(Debug, Clone, PartialEq)]
pub struct Key {
    /// The key's text.
    pub name: String,
    /// Where it was written.
    pub pos: Pos,
}

/// A syntax error of the document.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{pos}: {message}")]
pub struct SyntaxError {
    /// Where.
    pub pos: Pos,
    /// What.
    pub message: String,
}

fn pos_of(m: &saphyr_parser::Marker) -> Pos {
    Pos {
        line: m.line(),
        col: m.col() + 1,
    }
}

enum Open {
    Seq(Pos, usize, Vec<Node>),
    Map(Pos, usize, Vec<(Key, Node)>, Option<Key>),
}

impl Open {
    fn pos(&self) -> Pos {
        match self {
            Open::Seq(p, ..) | Open::Map(p, ..) => *p,
        }
    }
}

/// Parses one YAML document (an empty text is an empty mapping).
pub fn parse(text: &str) -> Result<Node, SyntaxError> {
    let mut stack: Vec<Open> = Vec::new();
    // Anchored nodes with their sizes in nodes.
    let mut anchors: HashMap<usize, (Node, usize)> = HashMap::new();
    let mut nodes = NodeCount(0);
    let mut root: Option<Node> = None;
    let mut documents = 0;
    for item in Parser::new_from_str(text) {
        let (event, span) = item.map_err(|e| syntax_error(text, &stack, &e))?;
        let pos = pos_of(&span.start);
        let complete = match event {
            Event::StreamStart | Event::StreamEnd | Event::DocumentEnd | Event::Nothing => None,
            Event::DocumentStart(_) => {
                documents += 1;
                if documents > 1 {
                    return Err(SyntaxError {
                        pos,
                        message:
                            "more than one YAML document (`---`); a description is one document"
                                .to_owned(),
                    });
                }
                None
            }
            Event::Alias(id) => match anchors.get(&id) {
                Some((node, size)) => {
                    nodes.add(*size, pos)?;
                    Some((0, node.clone()))
                }
                None => {
                    return Err(SyntaxError {
                        pos,
                        message: "alias to an unknown anchor".to_owned(),
                    })
                }
            },
            Event::Scalar(text, style, anchor, tag) => {
                refuse_tag(tag.is_some(), pos)?;
                nodes.add(1, pos)?;
                let value = Value::Scalar {
                    text: text.into_owned(),
                    quoted: !matches!(style, ScalarStyle::Plain),
                };
                Some((anchor, Node { pos, value }))
            }
            Event::SequenceStart(anchor, tag) => {
                refuse_tag(tag.is_some(), pos)?;
                nodes.add(1, pos)?;
                depth_check(stack.len(), pos)?;
                stack.push(Open::Seq(pos, anchor, Vec::new()));
                None
            }
            Event::MappingStart(anchor, tag) => {
                refuse_tag(tag.is_some(), pos)?;
                nodes.add(1, pos)?;
                depth_check(stack.len(), pos)?;
                stack.push(Open::Map(pos, anchor, Vec::new(), None));
                None
            }
            Event::SequenceEnd => match stack.pop() {
                Some(Open::Seq(p, anchor, items)) => Some((
                    anchor,
                    Node {
                        pos: p,
                        value: Value::Seq(items),
                    },
                )),
                _ => return Err(unbalanced(pos)),
            },
            Event::MappingEnd => match stack.pop() {
                Some(Open::Map(p, anchor, entries, None)) => Some((
                    anchor,
                    Node {
                        pos: p,
                        value: Value::Map(entries),
                    },
                )),
                _ => return Err(unbalanced(pos)),
            },
        };
        let Some((anchor, node)) = complete else {
            continue;
        };
        if anchor > 0 {
            anchors.insert(anchor, (node.clone(), size(&node)));
        }
        attach(&mut stack, &mut root, node)?;
    }
    Ok(root.unwrap_or(Node {
        pos: Pos { line: 1, col: 1 },
        value: Value::Map(Vec::new()),
    }))
}

/// Places a complete `node` in the collection open on top of `stack` (the `root` when none
/// is): an item of a sequence, a mapping's next key (a plain name, not written before) or the
/// value of its pending key.
fn attach(stack: &mut [Open], root: &mut Option<Node>, node: Node) -> Result<(), SyntaxError> {
    match stack.last_mut() {
        None => *root = Some(node),
        Some(Open::Seq(_, _, items)) => items.push(node),
        Some(Open::Map(_, _, entries, pending)) => match pending.take() {
            None => {
                let Value::Scalar { text, .. } = node.value else {
                    return Err(SyntaxError {
                        pos: node.pos,
                        message: "a mapping key must be a plain name, not a collection".to_owned(),
                    });
                };
                if let Some((first, _)) = entries.iter().find(|(k, _)| k.name == text) {
                    return Err(SyntaxError {
                        pos: node.pos,
                        message: format!(
                            "duplicate key `{text}` (first written at line {})",
                            first.pos.line
                        ),
                    });
                }
                *pending = Some(Key {
                    name: text,
                    pos: node.pos,
                });
            }
            Some(key) => entries.push((key, node)),
        },
    }
    Ok(())
}

/// Nodes read so far, aliases expanded, against [`MAX_NODES`].
struct NodeCount(usize);

impl NodeCount {
    /// Counts `n` more nodes, refusing at `pos` beyond [`MAX_NODES`].
    fn add(&mut self, n: usize, pos: Pos) -> Result<(), SyntaxError> {
        self.0 += n;
        if self.0 > MAX_NODES {
            return Err(SyntaxError {
                pos,
                message: format!(
                    "more than {MAX_NODES} nodes with the aliases expanded; a description is far smaller"
                ),
            });
        }
        Ok(())
    }
}

/// Nodes in `node`, itself included.
fn size(node: &Node) -> usize {
    match &node.value {
        Value::Scalar { .. } => 1,
        Value::Seq(items) => 1 + items.iter().map(size).sum::<usize>(),
        Value::Map(entries) => 1 + entries.iter().map(|(_, v)| 1 + size(v)).sum::<usize>(),
    }
}

fn refuse_tag(tagged: bool, pos: Pos) -> Result<(), SyntaxError> {
    if tagged {
        Err(SyntaxError {
            pos,
            message: "YAML tags (`!name`) are not part of the description format".to_owned(),
        })
    } else {
        Ok(())
    }
}

fn depth_check(depth: usize, pos: Pos) -> Result<(), SyntaxError> {
    if depth >= MAX_DEPTH {
        Err(SyntaxError {
            pos,
            message: format!("nested deeper than {MAX_DEPTH} levels"),
        })
    } else {
        Ok(())
    }
}

/// The parser's error `e`, or, when the text leaves a flow collection open that the parser
/// had open when it failed (`stack`), that collection's opening bracket.
fn syntax_error(text: &str, stack: &[Open], e: &saphyr_parser::ScanError) -> SyntaxError {
    let at = pos_of(e.marker());
    let parser = SyntaxError {
        pos: at,
        message: e.info().to_owned(),
    };
    let Some(u) = unclosed_flow(text) else {
        return parser;
    };
    if !stack.iter().any(|o| o.pos() == u.pos) {
        return parser;
    }
    let (kind, close) = match u.open {
        '{' => ("mapping", '}'),
        _ => ("sequence", ']'),
    };
    let message = match u.wrong_close {
        Some((c, p)) => format!(
            "unclosed flow {kind} `{}` opened here: close it with `{close}` before the `{c}` at line {}, column {}",
            u.open, p.line, p.col
        ),
        None => format!(
            "unclosed flow {kind} `{}` opened here: close it with `{close}` (the parser stopped at line {}, column {}: {})",
            u.open, at.line, at.col, parser.message
        ),
    };
    SyntaxError {
        pos: u.pos,
        message,
    }
}

/// A flow collection's opening bracket that the text does not close ([`unclosed_flow`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Unclosed {
    /// `{` or `[`.
    open: char,
    /// Where it was written.
    pos: Pos,
    /// The closing bracket of the other kind met while it was the innermost open one, if that
    /// is how it was found.
    wrong_close: Option<(char, Pos)>,
}

/// The first flow collection the text leaves open, by a scan of its brackets: the innermost
/// one open when a closing bracket of the other kind comes, when a line is indented no deeper
/// than the block the outermost open one sits in (its content must be indented deeper), or
/// at the end of the text. Quoted strings (escapes included), comments and block scalars
/// (`|`, `>`) are skipped, and outside flow collections a bracket or a quote counts only where
/// a node starts (after `key: `, `- `, at a line's start): `doc: it's [so]` is plain text.
fn unclosed_flow(text: &str) -> Option<Unclosed> {
    let mut scan = FlowScan {
        open: Vec::new(),
        limit: 0,
        quote: None,
        block_scalar: None,
    };
    for (l, line) in text.lines().enumerate() {
        let chars: Vec<char> = line.chars().collect();
        let indent = chars.iter().take_while(|&&c| c == ' ').count();
        let blank = matches!(chars.get(indent), None | Some('#'));
        if let Some(n) = scan.block_scalar {
            if blank || indent > n {
                continue;
            }
            scan.block_scalar = None;
        }
        if scan.quote.is_none()
            && !scan.open.is_empty()
            && !blank
            && (indent as isize) <= scan.limit
        {
            return scan.innermost();
        }
        if let ControlFlow::Break(found) = scan.line(l, &chars, indent) {
            return found;
        }
    }
    scan.innermost()
}

/// The state of [`unclosed_flow`]'s scan between lines.
struct FlowScan {
    /// Open flow brackets with where they opened, innermost last.
    open: Vec<(char, Pos)>,
    /// Lines indented no deeper than this close the block the outermost open collection is in.
    limit: isize,
    /// The quote a string open across lines started with.
    quote: Option<char>,
    /// The indentation of the line a block scalar starts on: deeper lines are its text.
    block_scalar: Option<usize>,
}

impl FlowScan {
    /// The innermost open bracket, as left unclosed.
    fn innermost(&mut self) -> Option<Unclosed> {
        self.open.pop().map(|(c, pos)| Unclosed {
            open: c,
            pos,
            wrong_close: None,
        })
    }

    /// Scans line `l` (its characters `chars`, indented by `indent`) for brackets; breaks with
    /// a bracket closed by the wrong kind, or with `None` at a close without an opening
    /// (not a case of an unclosed bracket).
    fn line(&mut self, l: usize, chars: &[char], indent: usize) -> ControlFlow<Option<Unclosed>> {
        // Whether a node may start here.
        let mut start = true;
        let mut i = 0;
        while i < chars.len() {
            let c = chars[i];
            let next = chars.get(i + 1).copied();
            let flow = !self.open.is_empty();
            if let Some(q) = self.quote {
                match (q, c) {
                    ('"', '\\') => i += 1,
                    ('\'', '\'') if next == Some('\'') => i += 1,
                    ('"', '"') | ('\'', '\'') => self.quote = None,
                    _ => {}
                }
                i += 1;
                continue;
            }
            match c {
                ' ' | '\t' => {}
                '#' if i == 0 || chars[i - 1].is_whitespace() => break,
                '"' | '\'' if start => {
                    self.quote = Some(c);
                    start = false;
                }
                '{' | '[' if start || flow => {
                    if !flow {
                        // Content lines of a collection that opens its line belong to the
                        // block above it; else to the line's own block.
                        let opens_line = i == indent;
                        self.limit = indent as isize - isize::from(opens_line);
                    }
                    self.open.push((
                        c,
                        Pos {
                            line: l + 1,
                            col: i + 1,
                        },
                    ));
                    start = true;
                }
                '}' | ']' if flow => {
                    let Some((o, pos)) = self.open.pop() else {
                        return ControlFlow::Break(None);
                    };
                    if (o == '{') != (c == '}') {
                        return ControlFlow::Break(Some(Unclosed {
                            open: o,
                            pos,
                            wrong_close: Some((
                                c,
                                Pos {
                                    line: l + 1,
                                    col: i + 1,
                                },
                            )),
                        }));
                    }
                    start = false;
                }
                ',' if flow => start = true,
                ':' if flow || next.is_none_or(char::is_whitespace) => start = true,
                '-' | '?' if start && !flow && next.is_none_or(char::is_whitespace) => {}
                '|' | '>' if start && !flow => {
                    self.block_scalar = Some(indent);
                    break;
                }
                // An anchor or a tag: the node follows.
                '&' | '!' if start => {
                    while chars.get(i + 1).is_some_and(|c| !c.is_whitespace()) {
                        i += 1;
                    }
                }
                _ => start = false,
            }
            i += 1;
        }
        ControlFlow::Continue(())
    }
}

fn unbalanced(pos: Pos) -> SyntaxError {
    SyntaxError {
        pos,
        message: "unbalanced collection".to_owned(),
    }
}

impl Node {
    /// A short description of the node's kind for messages ("a mapping", "`abc`").
    pub fn describe(&self) -> String {
        match &self.value {
            Value::Scalar { text, .. } if text.chars().count() > 60 => {
                format!("`{}...`", text.chars().take(57).collect::<String>())
            }
            Value::Scalar { text, .. } => format!("`{text}`"),
            Value::Seq(_) => "a list".to_owned(),
            Value::Map(_) => "a mapping".to_owned(),
        }
    }

    /// The scalar text, if a scalar.
    pub fn as_scalar(&self) -> Option<&str> {
        match &self.value {
            Value::Scalar { text, .. } => Some(text),
            _ => None,
        }
    }

    /// The entries, if a mapping.
    pub fn as_map(&self) -> Option<&[(Key, Node)]> {
        match &self.value {
            Value::Map(m) => Some(m),
            _ => None,
        }
    }

    /// The items, if a sequence.
    pub fn as_seq(&self) -> Option<&[Node]> {
        match &self.value {
            Value::Seq(s) => Some(s),
            _ => None,
        }
    }

    /// Whether this is a YAML null (`~`, `null`, or nothing).
    pub fn is_null(&self) -> bool {
        matches!(&self.value, Value::Scalar { text, quoted: false } if matches!(text.as_str(), "" | "~" | "null" | "Null" | "NULL"))
    }

    /// The scalar as a number when it is written as one (YAML 1.2 core schema: decimal,
    /// exponent, `.inf`, `.nan`; underscores are not digits), else `None`.
    pub fn as_number(&self) -> Option<f64> {
        match &self.value {
            Value::Scalar {
                text,
                quoted: false,
            } => parse_number(text),
            _ => None,
        }
    }
}

/// A YAML 1.2 core-schema number (`1`, `-2.5e-3`, `.inf`, `-.inf`, `.nan`), as f64.
pub fn parse_number(text: &str) -> Option<f64> {
    match text {
        ".inf" | ".Inf" | ".INF" | "+.inf" | "+.Inf" | "+.INF" => return Some(f64::INFINITY),
        "-.inf" | "-.Inf" | "-.INF" => return Some(f64::NEG_INFINITY),
        ".nan" | ".NaN" | ".NAN" => return Some(f64::NAN),
        _ => {}
    }
    let body = text.strip_prefix(['+', '-']).unwrap_or(text);
    let starts_ok = body.starts_with(|c: char| c.is_ascii_digit())
        || (body.starts_with('.') && body[1..].starts_with(|c: char| c.is_ascii_digit()));
    if !starts_ok
        || !body
            .chars()
            .all(|c| c.is_ascii_digit() || "+-.eE".contains(c))
    {
        return None;
    }
    text.parse::<f64>().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_carry_lines_and_keys_keep_their_order() {
        let doc = parse("a: 1\nb:\n  c: [x, 'y']\n  d: ~\n").unwrap();
        let m = doc.as_map().unwrap();
        assert_eq!(m[0].0.name, "a");
        assert_eq!(m[0].0.pos, Pos { line: 1, col: 1 });
        assert_eq!(m[1].0.name, "b");
        let inner = m[1].1.as_map().unwrap();
        assert_eq!(inner[0].0.pos.line, 3);
        let list = inner[0].1.as_seq().unwrap();
        assert_eq!(
            list[1].value,
            Value::Scalar {
                text: "y".into(),
                quoted: true
            }
        );
        assert!(inner[1].1.is_null());
        assert_eq!(m[0].1.as_number(), Some(1.0));
    }

    #[test]
    fn duplicate_keys_tags_and_many_documents_are_refused_at_their_line() {
        let e = parse("a: 1\nb: 2\na: 3\n").unwrap_err();
        assert_eq!(e.pos.line, 3);
        assert!(e.message.contains("duplicate key `a`") && e.message.contains("line 1"));
        assert_eq!(parse("a: !foo 1\n").unwrap_err().pos.line, 1);
        assert!(parse("a: 1\n---\nb: 2\n")
            .unwrap_err()
            .message
            .contains("more than one"));
        assert!(parse("a: [1, 2\n").is_err());
        assert!(parse("{[1]: 2}")
            .unwrap_err()
            .message
            .contains("plain name"));
    }

    #[test]
    fn aliases_copy_the_anchored_node() {
        let doc = parse("a: &w {k: 1}\nb: *w\n").unwrap();
        let m = doc.as_map().unwrap();
        assert_eq!(m[0].1.value, m[1].1.value);
        assert!(parse("b: *nope\n").is_err());
    }

    #[test]
    fn numbers_follow_the_core_schema() {
        for (text, want) in [
            ("1", 1.0),
            ("-2.5e-3", -2.5e-3),
            ("1.91e+6", 1.91e6),
            (".5", 0.5),
        ] {
            assert_eq!(parse_number(text), Some(want), "{text}");
        }
        assert_eq!(parse_number(".inf"), Some(f64::INFINITY));
        assert!(parse_number(".nan").unwrap().is_nan());
        for text in [
            "l_c", "1_000", "0x10", "", "-", "e5", "inf", "nan", "1.2.3x",
        ] {
            assert_eq!(parse_number(text), None, "{text}");
        }
    }

    #[test]
    fn exponential_aliases_are_refused() {
        let mut text = String::from("a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n");
        for i in 1..9 {
            let p = format!("*a{}", i - 1);
            text += &format!("a{i}: &a{i} [{}]\n", vec![p; 10].join(", "));
        }
        let e = parse(&text).unwrap_err();
        assert!(e.message.contains("aliases expanded"), "{e}");
        assert_eq!(e.pos.line, 5); // a4 would hold 111 111 nodes
    }

    /// The error of `text`, which must not parse.
    fn error(text: &str) -> SyntaxError {
        parse(text).expect_err("must be refused")
    }

    /// An unclosed `{` in a nested map is reported at the brace, not where the parser stopped
    /// (the next key, a line later), with the parser's words kept.
    #[test]
    fn an_unclosed_flow_mapping_is_reported_where_it_opens() {
        let text = "a:\n  b: {x: 1, y: 2\n  c: 3\nd: 4\n";
        let e = error(text);
        assert_eq!(e.pos, Pos { line: 2, col: 6 }, "{e}");
        assert!(
            e.message
                .starts_with("unclosed flow mapping `{` opened here"),
            "{e}"
        );
        assert!(e.message.contains("close it with `}`"), "{e}");
        assert!(e.message.contains("the parser stopped at line 3"), "{e}");
        // At the end of the text too.
        let e = error("a: 1\nb: {x: 1,\n    y: 2\n");
        assert_eq!(e.pos, Pos { line: 2, col: 4 }, "{e}");
        assert!(e.message.contains("flow mapping"), "{e}");
    }

    /// An unclosed `[`, at the end of its line or closed by the wrong bracket.
    #[test]
    fn an_unclosed_flow_sequence_is_reported_where_it_opens() {
        let e = error("a:\n  b: [1, 2\n  c: 3\n");
        assert_eq!(e.pos, Pos { line: 2, col: 6 }, "{e}");
        assert!(
            e.message
                .starts_with("unclosed flow sequence `[` opened here"),
            "{e}"
        );
        assert!(e.message.contains("close it with `]`"), "{e}");
        let e = error("a: {r: {f: [0.8, 1.2}, d: x}\nb: 1\n");
        assert_eq!(e.pos, Pos { line: 1, col: 12 }, "{e}");
        assert!(
            e.message.contains("before the `}` at line 1, column 21"),
            "{e}"
        );
    }

    /// Brackets inside quoted strings, comments, block scalars and plain text do not count:
    /// the `{` left open is the real one, and a document whose only fault is elsewhere keeps
    /// the parser's message and position.
    #[test]
    fn quoted_and_plain_brackets_are_not_mistaken_for_flow_collections() {
        let text = concat!(
            "doc: >-\n  text with { and [\nnote: it's [so] {or} (not\n",
            "a:\n  b: {d: \"}{\", e: '[''{', f: 1  # a } in a comment\n",
            "  c: 3\n"
        );
        let e = error(text);
        assert_eq!(e.pos, Pos { line: 5, col: 6 }, "{e}");
        assert!(e.message.contains("flow mapping"), "{e}");
        assert_eq!(unclosed_flow(&text.replace("f: 1 ", "f: 1}")), None);
        // Balanced brackets, a different fault: the parser's own report.
        let e = error("a: {x: 1 y: 2}\n");
        assert!(!e.message.contains("unclosed"), "{e}");
        assert_eq!(e.pos.line, 1);
        // A bracket the scan finds unclosed but the parser never opened (it stopped before):
        // the parser's report.
        let e = error("a: b: c\nd: [1\n");
        assert_eq!(e.pos.line, 1, "{e}");
        assert!(!e.message.contains("unclosed"), "{e}");
    }

    #[test]
    fn deep_nesting_is_refused() {
        let text = "[".repeat(MAX_DEPTH + 1) + &"]".repeat(MAX_DEPTH + 1);
        assert!(parse(&text).unwrap_err().message.contains("nested deeper"));
    }
}
