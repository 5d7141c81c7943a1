//! Stored reference tables of the slow tests, in the manner of Basilisk's `.ref` files: a test
//! computes its table and compares it with `tests/ref/NAME.ref`, plain whitespace-separated text
//! whose `#` lines are comments and whose first other line names the columns.
//!
//! With the environment variable `GRANRS_BLESS=1` the test writes the table to its `.ref` file
//! instead of comparing (regenerating it after an intended change of the numbers).
//!
//! Each column states how it is compared: a label (the settings naming a row) or an integer
//! (iteration counts, step counts) must match exactly; a floating-point measure within a relative tolerance (with an
//! absolute floor for values that are differences of nearly equal numbers).

// Each test binary that includes this file uses only part of it.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::path::PathBuf;

/// How a column is compared with its stored value.
#[derive(Clone, Copy, Debug)]
pub enum Tol {
    /// A label naming the row (a case's settings), matched exactly.
    Label,
    /// Text that must match exactly: an integer.
    Exact,
    /// |got − expected| ≤ rel · |expected| + abs.
    Close { rel: f64, abs: f64 },
}

/// One column: its name in the header line and its comparison.
pub struct Column {
    pub name: &'static str,
    pub tol: Tol,
}

/// Formats a float for a table: the shortest text that reads back to the same f64.
pub fn float(x: f64) -> String {
    format!("{x:e}")
}

fn ref_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("ref").join(format!("{name}.ref"))
}

fn render(header: &[&str], columns: &[Column], rows: &[Vec<String>]) -> String {
    let names: Vec<&str> = columns.iter().map(|c| c.name).collect();
    let mut width: Vec<usize> = names.iter().map(|n| n.len()).collect();
    for row in rows {
        for (w, v) in width.iter_mut().zip(row) {
            *w = (*w).max(v.len());
        }
    }
    let mut out = String::new();
    for line in header {
        writeln!(out, "# {line}").unwrap();
    }
    let line = |cells: &[&str]| -> String {
        let padded: Vec<String> = cells.iter().zip(&width).map(|(c, w)| format!("{c:<w$}")).collect();
        padded.join("  ").trim_end().to_string()
    };
    writeln!(out, "{}", line(&names)).unwrap();
    for row in rows {
        let cells: Vec<&str> = row.iter().map(String::as_str).collect();
        writeln!(out, "{}", line(&cells)).unwrap();
    }
    out
}

/// Compares `rows` with the stored table `tests/ref/{name}.ref` (or writes it under
/// `GRANRS_BLESS=1`, with `header` as its comment lines). Panics with every differing cell
/// (row, column, got, expected, tolerance) when the tables differ.
pub fn check(name: &str, header: &[&str], columns: &[Column], rows: &[Vec<String>]) {
    for (r, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), columns.len(), "{name}: row {r} has {} cells for {} columns", row.len(), columns.len());
        assert!(row.iter().all(|c| !c.is_empty() && !c.contains(char::is_whitespace)), "{name}: row {r} has an empty cell or one with spaces: {row:?}");
    }
    let table = render(header, columns, rows);
    println!("{table}");
    let path = ref_path(name);
    if std::env::var("GRANRS_BLESS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &table).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
        println!("GRANRS_BLESS=1: wrote {}", path.display());
        return;
    }
    let stored =
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read the reference table {} ({e}); write it with GRANRS_BLESS=1", path.display()));
    let mut lines = stored.lines().filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let names: Vec<&str> = columns.iter().map(|c| c.name).collect();
    let stored_names: Vec<&str> = lines.next().map(|l| l.split_whitespace().collect()).unwrap_or_default();
    assert_eq!(stored_names, names, "{name}: the columns of {} differ from the test's", path.display());
    let expected: Vec<Vec<&str>> = lines.map(|l| l.split_whitespace().collect()).collect();
    let mut diff = Vec::new();
    if expected.len() != rows.len() {
        diff.push(format!("{} rows computed, {} stored", rows.len(), expected.len()));
    }
    for (r, (got, exp)) in rows.iter().zip(&expected).enumerate() {
        let label: Vec<&str> = columns.iter().zip(got).filter(|(c, _)| matches!(c.tol, Tol::Label)).map(|(_, g)| g.as_str()).collect();
        let label = label.join(" ");
        if exp.len() != columns.len() {
            diff.push(format!("row {r}: {} stored cells for {} columns", exp.len(), columns.len()));
            continue;
        }
        for ((col, g), e) in columns.iter().zip(got).zip(exp) {
            let bad = match col.tol {
                Tol::Label | Tol::Exact => (g != e).then(|| "exact match".to_string()),
                Tol::Close { rel, abs } => {
                    let (gv, ev): (f64, f64) = (g.parse().unwrap(), e.parse().unwrap_or(f64::NAN));
                    let d = (gv - ev).abs();
                    // a NaN on either side makes d NaN, which is not within any bound
                    let within = d.is_finite() && d <= rel * ev.abs() + abs;
                    (!within).then(|| format!("|difference| {d:.3e} > {rel:e} relative + {abs:e}"))
                }
            };
            if let Some(why) = bad {
                diff.push(format!("row {r} ({label}), column {}: got {g}, expected {e} ({why})", col.name));
            }
        }
    }
    assert!(
        diff.is_empty(),
        "{name}: the computed table differs from {}:\n  {}\n(if the change is intended, regenerate the table with GRANRS_BLESS=1)",
        path.display(),
        diff.join("\n  ")
    );
}
