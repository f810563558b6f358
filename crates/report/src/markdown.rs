//! Markdown (GitHub-flavoured) tables: a header row, a `|---|` rule, one row per record.
//!
//! A cell's `|` would end the cell early and shift every column after it: it is written `\|`,
//! which renders as `|`. A line break would end the row: it is written `<br>`.
//!
//! ```
//! let md = report::markdown::table(&["a", "b"], &[vec!["x|y".into(), "1".into()]]);
//! assert_eq!(md, "| a | b |\n|---|---|\n| x\\|y | 1 |\n");
//! ```

/// A cell's text with `|` escaped and line breaks as `<br>`.
pub fn escape(cell: &str) -> String {
    cell.replace('|', "\\|")
        .replace("\r\n", "<br>")
        .replace(['\n', '\r'], "<br>")
}

/// A table: header, rule, rows, each line ending in `\n`. Rows shorter than the header are
/// padded with empty cells, so the table stays rectangular.
pub fn table<S: AsRef<str>>(header: &[S], rows: &[Vec<String>]) -> String {
    let line = |cells: &mut dyn Iterator<Item = &str>| {
        let mut s = String::from("|");
        for c in cells {
            s.push(' ');
            s.push_str(&escape(c));
            s.push_str(" |");
        }
        s.push('\n');
        s
    };
    let mut out = line(&mut header.iter().map(AsRef::as_ref));
    out.push('|');
    out.push_str(&"---|".repeat(header.len()));
    out.push('\n');
    for r in rows {
        let pad = header.len().saturating_sub(r.len());
        out.push_str(&line(
            &mut r
                .iter()
                .map(String::as_str)
                .chain(std::iter::repeat_n("", pad)),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Splits a rendered row into cells the way a GFM renderer does: at every `|` not
    /// preceded by a backslash.
    fn cells(row: &str) -> Vec<String> {
        let inner = row
            .trim_end()
            .strip_prefix('|')
            .unwrap()
            .strip_suffix('|')
            .unwrap();
        let mut out = vec![String::new()];
        let mut prev = ' ';
        for ch in inner.chars() {
            if ch == '|' && prev != '\\' {
                out.push(String::new());
            } else {
                out.last_mut().unwrap().push(ch);
            }
            prev = ch;
        }
        out.iter().map(|c| c.trim().replace("\\|", "|")).collect()
    }

    #[test]
    fn a_pipe_in_a_cell_stays_in_its_cell() {
        let md = table(
            &["Algorithm", "Name"],
            &[vec!["1".into(), "FNO | data only".into()]],
        );
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[1], "|---|---|");
        assert_eq!(cells(lines[2]), ["1", "FNO | data only"]);
        assert_eq!(cells(lines[0]), ["Algorithm", "Name"]);
    }

    #[test]
    fn a_line_break_in_a_cell_keeps_the_row_on_one_line() {
        let md = table(&["a"], &[vec!["two\nlines\r\nhere".into()]]);
        assert_eq!(md, "| a |\n|---|\n| two<br>lines<br>here |\n");
    }

    #[test]
    fn short_rows_are_padded() {
        assert_eq!(
            table(&["a", "b"], &[vec!["1".into()]]),
            "| a | b |\n|---|---|\n| 1 |  |\n"
        );
    }
}
