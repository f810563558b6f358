//! Finding the line of a stage, a field or a word in the pipeline file's text.
//!
//! serde_yaml reports positions for syntax and type errors only; semantic errors (a missing
//! dependency, a cycle, an unknown `--set` key) are located here by a small indentation-aware
//! scan of the text: the stage's key under `stages:`, then a field inside that stage's block,
//! then a word inside that field's block. Lines are 1-based; when nothing better is found the
//! enclosing line is returned, so a message always names a line.

/// A line index over the pipeline file's text.
pub struct Locator<'a> {
    lines: Vec<&'a str>,
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start().len()
}

fn is_content(line: &str) -> bool {
    let t = line.trim_start();
    !t.is_empty() && !t.starts_with('#')
}

/// The mapping key a line starts with, unquoted (`  "a b": 1` -> `a b`).
fn key_of(line: &str) -> Option<&str> {
    let t = line.trim_start();
    let t = t.strip_prefix("- ").unwrap_or(t);
    for q in ['"', '\''] {
        if let Some(rest) = t.strip_prefix(q) {
            let end = rest.find(q)?;
            return rest[end + 1..]
                .trim_start()
                .starts_with(':')
                .then(|| &rest[..end]);
        }
    }
    let colon = t.find(':')?;
    let after = &t[colon + 1..];
    (after.is_empty() || after.starts_with(' ') || after.starts_with('\t'))
        .then(|| t[..colon].trim_end())
}

fn is_word_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_' || c == '-'
}

/// Whether `word` occurs in `line` with non-word characters (or the ends) on both sides.
fn has_word(line: &str, word: &str) -> bool {
    let code = line.split(" #").next().unwrap_or(line);
    code.match_indices(word).any(|(i, _)| {
        let before = code[..i].chars().next_back();
        let after = code[i + word.len()..].chars().next();
        !before.is_some_and(is_word_char) && !after.is_some_and(is_word_char)
    })
}

impl<'a> Locator<'a> {
    /// Indexes `text`.
    pub fn new(text: &'a str) -> Self {
        Self {
            lines: text.lines().collect(),
        }
    }

    /// 0-based index one past the block that starts at line `start` (0-based): the first
    /// following content line indented no deeper than `start`.
    fn block_end(&self, start: usize) -> usize {
        let ind = indent(self.lines[start]);
        (start + 1..self.lines.len())
            .find(|&j| is_content(self.lines[j]) && indent(self.lines[j]) <= ind)
            .unwrap_or(self.lines.len())
    }

    fn find_key(&self, from: usize, to: usize, key: &str) -> Option<usize> {
        (from..to).find(|&j| is_content(self.lines[j]) && key_of(self.lines[j]) == Some(key))
    }

    /// 0-based index of the top-level `key:` line.
    fn top(&self, key: &str) -> Option<usize> {
        (0..self.lines.len()).find(|&j| {
            indent(self.lines[j]) == 0
                && is_content(self.lines[j])
                && key_of(self.lines[j]) == Some(key)
        })
    }

    /// Line of the second `key:` at the indentation of the first one found from line `from`
    /// (1-based): where a duplicate key is.
    pub fn duplicate_line(&self, from: usize, key: &str) -> Option<usize> {
        let start = from.saturating_sub(1);
        let first = (start..self.lines.len()).find(|&j| key_of(self.lines[j]) == Some(key))?;
        let ind = indent(self.lines[first]);
        // Only within the enclosing mapping: stop at the first line indented less.
        let end = (first + 1..self.lines.len())
            .find(|&j| is_content(self.lines[j]) && indent(self.lines[j]) < ind)
            .unwrap_or(self.lines.len());
        (first + 1..end)
            .find(|&j| indent(self.lines[j]) == ind && key_of(self.lines[j]) == Some(key))
            .map(|j| j + 1)
    }

    /// Line of a top-level key such as `bin_dir` or `stages` (1 when absent).
    pub fn top_line(&self, key: &str) -> usize {
        self.top(key).map_or(1, |j| j + 1)
    }

    fn stage0(&self, stage: &str) -> Option<usize> {
        let s = self.top("stages")?;
        let end = self.block_end(s);
        self.find_key(s + 1, end, stage)
    }

    /// Line of the stage's name under `stages:`.
    pub fn stage_line(&self, stage: &str) -> usize {
        self.stage0(stage)
            .map_or_else(|| self.top_line("stages"), |j| j + 1)
    }

    /// The stage's own `field:` line: a key at the indentation of the stage's first field, not
    /// one nested deeper (`inputs: {params: ...}` written as a block names no `params` field).
    fn field0(&self, stage: &str, field: &str) -> Option<usize> {
        let s = self.stage0(stage)?;
        let end = self.block_end(s);
        let child = (s + 1..end).find(|&j| is_content(self.lines[j]))?;
        let ind = indent(self.lines[child]);
        (child..end).find(|&j| {
            is_content(self.lines[j])
                && indent(self.lines[j]) == ind
                && key_of(self.lines[j]) == Some(field)
        })
    }

    /// Line of `field:` inside the stage's block (the stage's line when absent).
    pub fn field_line(&self, stage: &str, field: &str) -> usize {
        self.field0(stage, field)
            .map_or_else(|| self.stage_line(stage), |j| j + 1)
    }

    /// Line where `word` appears inside the stage's `field` (flow or block style); falls back
    /// to the field's line, or the stage's when the stage has no such field.
    pub fn word_line(&self, stage: &str, field: &str, word: &str) -> usize {
        self.word_line_if(stage, field, word).unwrap_or_else(|| {
            self.field0(stage, field)
                .map_or_else(|| self.stage_line(stage), |f| f + 1)
        })
    }

    /// Line where `word` appears inside the stage's `field`; `None` when it does not.
    pub fn word_line_if(&self, stage: &str, field: &str, word: &str) -> Option<usize> {
        let f = self.field0(stage, field)?;
        let end = self.block_end(f);
        let line_of = |j: usize| -> Option<usize> {
            let l = self.lines[j];
            // On the field's own line only the value part counts (`inputs: {a: b}`).
            let hay = if j == f {
                l.split_once(':').map_or("", |x| x.1)
            } else {
                l
            };
            has_word(hay, word).then_some(j + 1)
        };
        (f..end).find_map(line_of)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "\
bin_dir: target/release
stages:
  a:
    cmd: [x]
    params: {seed: 1}
  b:
    cmd: [x]
    inputs: {up: a}
    params:
      rate: 2.0
      # comment
      name: z
  'c':
    cmd: [x]
    inputs:
      params: b
    params:
      seed: 3
";

    #[test]
    fn finds_stages_fields_and_words() {
        let l = Locator::new(TEXT);
        assert_eq!(l.top_line("bin_dir"), 1);
        assert_eq!(l.stage_line("a"), 3);
        assert_eq!(l.stage_line("b"), 6);
        assert_eq!(l.stage_line("c"), 13);
        assert_eq!(l.field_line("b", "inputs"), 8);
        assert_eq!(l.word_line("b", "inputs", "a"), 8);
        assert_eq!(l.word_line("c", "inputs", "b"), 16);
        // A field is the stage's own key, not a key of the same name nested in another field.
        assert_eq!(l.field_line("c", "params"), 17);
        assert_eq!(l.word_line("c", "params", "seed"), 18);
        assert_eq!(l.word_line("b", "params", "name"), 12);
        assert_eq!(l.word_line("a", "params", "seed"), 5);
        // Fallbacks: unknown field -> stage line; unknown stage -> `stages:` line.
        assert_eq!(l.field_line("a", "shards"), 3);
        assert_eq!(l.stage_line("zz"), 2);
        assert_eq!(l.duplicate_line(3, "cmd"), None);
        let d = Locator::new("stages:\n  a:\n    cmd: [x]\n  a:\n    cmd: [y]\n");
        assert_eq!(d.duplicate_line(2, "a"), Some(4));
    }

    #[test]
    fn words_need_boundaries() {
        assert!(has_word("inputs: {up: a}", "a"));
        assert!(!has_word("inputs: {up: ab}", "a"));
        assert!(!has_word("x: sample-params", "params"));
    }
}
