//! Problems found in a description, each with its position, collected so one run reports all
//! of them.

use crate::yaml::Pos;

/// One problem: where and what.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    /// Where (line, column) in the description.
    pub pos: Pos,
    /// What is wrong and what was expected.
    pub message: String,
}

/// Problems of one description file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Diagnostics {
    /// The file (as given), for messages.
    pub file: String,
    /// The problems in the order found (sorted by position when reported).
    pub items: Vec<Diagnostic>,
}

impl Diagnostics {
    /// Records a problem.
    pub fn push(&mut self, pos: Pos, message: impl Into<String>) {
        self.items.push(Diagnostic {
            pos,
            message: message.into(),
        });
    }

    /// Whether nothing was found.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

impl std::fmt::Display for Diagnostics {
    /// `file:line:col: message`, one line per problem, in file order (control characters of
    /// the message escaped).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut items = self.items.clone();
        items.sort_by_key(|d| d.pos);
        for (i, d) in items.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{}:{}:{}: ", self.file, d.pos.line, d.pos.col)?;
            // One problem per line: line breaks and other controls quoted from the text are
            // shown escaped.
            for c in d.message.chars() {
                if c.is_control() || matches!(c, '\u{2028}' | '\u{2029}') {
                    write!(f, "{}", c.escape_debug())?;
                } else {
                    write!(f, "{c}")?;
                }
            }
        }
        Ok(())
    }
}
