//! Typed reading of YAML nodes with problems collected: a mapping's fields are taken by name,
//! unknown fields are reported with the allowed ones, and every value that is not what the
//! format expects becomes a [`crate::diag::Diagnostic`] at its position.

use crate::diag::Diagnostics;
use crate::expr::Expr;
use crate::yaml::{Key, Node, Pos, Value};

/// An expression-valued field: the parsed expression and where it was written.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The expression (a number is `Expr::Num`).
    pub expr: Expr,
    /// Where it was written.
    pub pos: Pos,
}

impl Field {
    /// A literal, positioned at `pos` (defaults).
    pub fn number(value: f64, pos: Pos) -> Self {
        Self {
            expr: Expr::Num(value),
            pos,
        }
    }
}

/// The fields of one mapping, read one by one.
pub struct MapReader<'a> {
    what: String,
    pos: Pos,
    entries: &'a [(Key, Node)],
    taken: Vec<bool>,
}

impl<'a> MapReader<'a> {
    /// Reads `node` as a mapping called `what` in messages; `None` (and a problem) if it is not
    /// one.
    pub fn new(node: &'a Node, what: &str, diag: &mut Diagnostics) -> Option<Self> {
        match &node.value {
            Value::Map(entries) => Some(Self {
                what: what.to_owned(),
                pos: node.pos,
                entries,
                taken: vec![false; entries.len()],
            }),
            _ if node.is_null() => Some(Self {
                what: what.to_owned(),
                pos: node.pos,
                entries: &[],
                taken: Vec::new(),
            }),
            _ => {
                diag.push(
                    node.pos,
                    format!("{what}: expected a mapping, found {}", node.describe()),
                );
                None
            }
        }
    }

    /// Where the mapping starts.
    pub fn pos(&self) -> Pos {
        self.pos
    }

    /// The field `name`, if present (marks it as read).
    pub fn get(&mut self, name: &str) -> Option<&'a Node> {
        let i = self.entries.iter().position(|(k, _)| k.name == name)?;
        self.taken[i] = true;
        Some(&self.entries[i].1)
    }

    /// The field `name`; a problem if absent.
    pub fn required(&mut self, name: &str, diag: &mut Diagnostics) -> Option<&'a Node> {
        let found = self.get(name);
        if found.is_none() {
            diag.push(self.pos, format!("{}: missing field `{name}`", self.what));
        }
        found
    }

    /// An expression field (a number or an expression string).
    pub fn expr(&mut self, name: &str, diag: &mut Diagnostics) -> Option<Field> {
        let node = self.get(name)?;
        read_expr(node, &format!("{}.{name}", self.what), diag)
    }

    /// A required expression field.
    pub fn required_expr(&mut self, name: &str, diag: &mut Diagnostics) -> Option<Field> {
        let node = self.required(name, diag)?;
        read_expr(node, &format!("{}.{name}", self.what), diag)
    }

    /// A string field.
    pub fn string(&mut self, name: &str, diag: &mut Diagnostics) -> Option<(String, Pos)> {
        let node = self.get(name)?;
        read_string(node, &format!("{}.{name}", self.what), diag)
    }

    /// A required string field.
    pub fn required_string(&mut self, name: &str, diag: &mut Diagnostics) -> Option<(String, Pos)> {
        let node = self.required(name, diag)?;
        read_string(node, &format!("{}.{name}", self.what), diag)
    }

    /// A number field (a literal, not an expression).
    pub fn number(&mut self, name: &str, diag: &mut Diagnostics) -> Option<(f64, Pos)> {
        let node = self.get(name)?;
        read_number(node, &format!("{}.{name}", self.what), diag).map(|v| (v, node.pos))
    }

    /// Reports every field not read, naming the allowed ones. Call after reading all fields.
    pub fn finish(self, allowed: &[&str], diag: &mut Diagnostics) {
        for ((key, _), taken) in self.entries.iter().zip(&self.taken) {
            if !taken {
                diag.push(
                    key.pos,
                    format!(
                        "{}: unknown field `{}`; allowed: {}",
                        self.what,
                        key.name,
                        allowed.join(", ")
                    ),
                );
            }
        }
    }

    /// The entries, for mappings whose keys are names chosen by the user.
    pub fn entries(&mut self) -> &'a [(Key, Node)] {
        self.taken.iter_mut().for_each(|t| *t = true);
        self.entries
    }
}

/// A node as an expression: a YAML number, or a string parsed by [`Expr::parse`].
pub fn read_expr(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<Field> {
    if let Some(v) = node.as_number() {
        if !v.is_finite() {
            diag.push(node.pos, format!("{what}: {v} is not a finite number"));
            return None;
        }
        return Some(Field {
            expr: Expr::Num(v),
            pos: node.pos,
        });
    }
    match &node.value {
        Value::Scalar { text, .. } if !node.is_null() => match Expr::parse(text) {
            Ok(expr) => Some(Field {
                expr,
                pos: node.pos,
            }),
            Err(e) => {
                diag.push(node.pos, format!("{what}: not an expression: {e}"));
                None
            }
        },
        _ => {
            diag.push(
                node.pos,
                format!(
                    "{what}: expected a number or an expression, found {}",
                    if node.is_null() {
                        "nothing".to_owned()
                    } else {
                        node.describe()
                    }
                ),
            );
            None
        }
    }
}

/// A node as a string (any scalar but null).
pub fn read_string(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<(String, Pos)> {
    match &node.value {
        Value::Scalar { text, .. } if !node.is_null() => Some((text.clone(), node.pos)),
        _ => {
            diag.push(
                node.pos,
                format!("{what}: expected a name, found {}", node.describe()),
            );
            None
        }
    }
}

/// A node as a finite literal number.
pub fn read_number(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<f64> {
    match node.as_number() {
        Some(v) if v.is_finite() => Some(v),
        _ => {
            diag.push(
                node.pos,
                format!(
                    "{what}: expected a finite number, found {}",
                    node.describe()
                ),
            );
            None
        }
    }
}

/// A node as a list of exactly `N` finite numbers (`[lo, hi]`).
pub fn read_pair(node: &Node, what: &str, diag: &mut Diagnostics) -> Option<[f64; 2]> {
    let Some(items) = node.as_seq() else {
        diag.push(
            node.pos,
            format!("{what}: expected `[lo, hi]`, found {}", node.describe()),
        );
        return None;
    };
    if items.len() != 2 {
        diag.push(
            node.pos,
            format!(
                "{what}: expected `[lo, hi]` (2 numbers), found {} items",
                items.len()
            ),
        );
        return None;
    }
    let lo = read_number(&items[0], what, diag)?;
    let hi = read_number(&items[1], what, diag)?;
    Some([lo, hi])
}

/// A list of names.
pub fn read_names(node: &Node, what: &str, diag: &mut Diagnostics) -> Vec<(String, Pos)> {
    match node.as_seq() {
        Some(items) => items
            .iter()
            .filter_map(|n| read_string(n, what, diag))
            .collect(),
        None => {
            diag.push(
                node.pos,
                format!(
                    "{what}: expected a list of names, found {}",
                    node.describe()
                ),
            );
            Vec::new()
        }
    }
}

/// Whether `name` can name a parameter, body, point or element: letters, digits and `_`
/// (element names may start with a digit: `1` is wheel 1's contact).
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}
