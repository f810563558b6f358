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

use saphyr_parser::{Event, Parser, ScalarStyle};
use std::collections::HashMap;

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

/// Parses one YAML document (an empty text is an empty mapping).
pub fn parse(text: &str) -> Result<Node, SyntaxError> {
    let mut stack: Vec<Open> = Vec::new();
    // Anchored nodes with their sizes in nodes.
    let mut anchors: HashMap<usize, (Node, usize)> = HashMap::new();
    let mut nodes = 0usize;
    let mut count = |n: usize, pos: Pos| -> Result<(), SyntaxError> {
        nodes += n;
        if nodes > MAX_NODES {
            return Err(SyntaxError {
                pos,
                message: format!(
                    "more than {MAX_NODES} nodes with the aliases expanded; a description is far smaller"
                ),
            });
        }
        Ok(())
    };
    let mut root: Option<Node> = None;
    let mut documents = 0;
    for item in Parser::new_from_str(text) {
        let (event, span) = item.map_err(|e| SyntaxError {
            pos: pos_of(e.marker()),
            message: e.info().to_owned(),
        })?;
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
                    count(*size, pos)?;
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
                count(1, pos)?;
                let quoted = !matches!(style, ScalarStyle::Plain);
                Some((
                    anchor,
                    Node {
                        pos,
                        value: Value::Scalar {
                            text: text.into_owned(),
                            quoted,
                        },
                    },
                ))
            }
            Event::SequenceStart(anchor, tag) => {
                refuse_tag(tag.is_some(), pos)?;
                count(1, pos)?;
                depth_check(stack.len(), pos)?;
                stack.push(Open::Seq(pos, anchor, Vec::new()));
                None
            }
            Event::MappingStart(anchor, tag) => {
                refuse_tag(tag.is_some(), pos)?;
                count(1, pos)?;
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
        match stack.last_mut() {
            None => root = Some(node),
            Some(Open::Seq(_, _, items)) => items.push(node),
            Some(Open::Map(_, _, entries, pending)) => match pending.take() {
                None => {
                    let Value::Scalar { text, .. } = node.value else {
                        return Err(SyntaxError {
                            pos: node.pos,
                            message: "a mapping key must be a plain name, not a collection"
                                .to_owned(),
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
    }
    Ok(root.unwrap_or(Node {
        pos: Pos { line: 1, col: 1 },
        value: Value::Map(Vec::new()),
    }))
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

    #[test]
    fn deep_nesting_is_refused() {
        let text = "[".repeat(MAX_DEPTH + 1) + &"]".repeat(MAX_DEPTH + 1);
        assert!(parse(&text).unwrap_err().message.contains("nested deeper"));
    }
}
