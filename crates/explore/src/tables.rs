//! The CSV tables of the pipeline's outputs (an evaluation's Table 4, a study's tables), read
//! whole as rows of strings for the page.

use std::path::Path;

/// Every row of the CSV file at `path` (the header row included), each a row of fields; an
/// error names the file.
pub fn read_csv(path: &Path) -> Result<Vec<Vec<String>>, String> {
    let mut r = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_path(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    r.records()
        .map(|rec| {
            rec.map(|r| r.iter().map(str::to_owned).collect())
                .map_err(|e| format!("{}: {e}", path.display()))
        })
        .collect()
}
