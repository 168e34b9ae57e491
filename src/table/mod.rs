//! Column tables for pandas: named columns of floats, integers or strings, all of one length, written
//! as CSV ([`csv`]) or Parquet ([`parquet`]) and read back from either (what `bfqi-ga export`
//! writes, and what logged datasets are read from).
//!
//! Missing values: a float column holds NaN (what pandas reads a missing float as), an integer or
//! string column holds `None` (pandas: a nullable integer / a `None` in an object column).

pub mod csv;
pub mod parquet;

use crate::error::{Error, Result};
use std::path::Path;

/// One column's values.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// 64-bit floats; NaN is missing.
    Float(Vec<f64>),
    /// 64-bit integers; `None` is missing.
    Int(Vec<Option<i64>>),
    /// UTF-8 strings; `None` is missing (an empty string is a value).
    Str(Vec<Option<String>>),
}

impl Column {
    /// Rows in the column.
    pub fn len(&self) -> usize {
        match self {
            Column::Float(v) => v.len(),
            Column::Int(v) => v.len(),
            Column::Str(v) => v.len(),
        }
    }

    /// Whether the column has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The type's name in messages and documentation (`float`, `int`, `string`).
    pub fn type_name(&self) -> &'static str {
        match self {
            Column::Float(_) => "float",
            Column::Int(_) => "int",
            Column::Str(_) => "string",
        }
    }

    /// An empty column of the same type.
    fn empty_like(&self) -> Column {
        match self {
            Column::Float(_) => Column::Float(Vec::new()),
            Column::Int(_) => Column::Int(Vec::new()),
            Column::Str(_) => Column::Str(Vec::new()),
        }
    }

    /// Appends `n` missing values.
    fn push_missing(&mut self, n: usize) {
        match self {
            Column::Float(v) => v.extend(std::iter::repeat_n(f64::NAN, n)),
            Column::Int(v) => v.extend(std::iter::repeat_n(None, n)),
            Column::Str(v) => v.extend(std::iter::repeat_n(None, n)),
        }
    }

    /// Appends `other`, of the same type (`false`, leaving `self` alone, when the types differ).
    fn append(&mut self, other: &Column) -> bool {
        match (self, other) {
            (Column::Float(a), Column::Float(b)) => a.extend_from_slice(b),
            (Column::Int(a), Column::Int(b)) => a.extend_from_slice(b),
            (Column::Str(a), Column::Str(b)) => a.extend_from_slice(b),
            _ => return false,
        }
        true
    }
}

/// Named columns of equal length.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Table {
    names: Vec<String>,
    columns: Vec<Column>,
}

impl Table {
    /// A table without columns.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a column at the right; refused when its name is taken or its length differs from the
    /// table's.
    pub fn push(&mut self, name: &str, column: Column) -> Result<()> {
        if self.names.iter().any(|n| n == name) {
            return Err(Error::Data(format!("table column '{name}' given twice")));
        }
        if let Some(first) = self.columns.first()
            && first.len() != column.len()
        {
            return Err(Error::Data(format!(
                "table column '{name}' has {} rows, the table {}",
                column.len(),
                first.len()
            )));
        }
        self.names.push(name.to_string());
        self.columns.push(column);
        Ok(())
    }

    /// The table of `names` and `columns` (as many), in linear time where [`Self::push`] per
    /// column is quadratic in the width (a file of 100,000 columns); refused, naming the column,
    /// when a name is taken twice or the lengths differ.
    fn from_parts(names: Vec<String>, columns: Vec<Column>) -> Result<Self> {
        if let Some(name) = first_repeated(&names) {
            return Err(Error::Data(format!("table column '{name}' given twice")));
        }
        if let Some(first) = columns.first()
            && let Some((name, c)) = names.iter().zip(&columns).find(|(_, c)| c.len() != first.len())
        {
            return Err(Error::Data(format!("table column '{name}' has {} rows, the table {}", c.len(), first.len())));
        }
        Ok(Table { names, columns })
    }

    /// Rows (0 for a table without columns).
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Column::len)
    }

    /// Columns.
    pub fn width(&self) -> usize {
        self.columns.len()
    }

    /// The column names, left to right.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The columns with their names, left to right.
    pub fn columns(&self) -> impl Iterator<Item = (&str, &Column)> {
        self.names.iter().map(String::as_str).zip(&self.columns)
    }

    /// The column called `name`.
    pub fn column(&self, name: &str) -> Option<&Column> {
        self.names.iter().position(|n| n == name).map(|i| &self.columns[i])
    }

    /// Appends the rows of `other` below this table's. Columns are matched by name: a column of
    /// only one of them is missing in the other's rows (it is added at the right when new); a
    /// column whose types differ is refused, naming it.
    pub fn append(&mut self, other: &Table) -> Result<()> {
        let (before, added) = (self.rows(), other.rows());
        for (name, col) in other.columns() {
            if self.column(name).is_none() {
                let mut c = col.empty_like();
                c.push_missing(before);
                self.names.push(name.to_string());
                self.columns.push(c);
            }
        }
        for (name, col) in self.names.iter().zip(&mut self.columns) {
            match other.column(name) {
                Some(o) => {
                    if !col.append(o) {
                        return Err(Error::Data(format!(
                            "table column '{name}' is {} in one table and {} in the other",
                            col.type_name(),
                            o.type_name()
                        )));
                    }
                }
                None => col.push_missing(added),
            }
        }
        Ok(())
    }
}

/// A table file's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Apache Parquet (snappy-compressed).
    Parquet,
    /// RFC 4180 CSV with a header line.
    Csv,
}

impl Format {
    /// The format a file's extension names (`.parquet`, `.pq`, `.csv`), if any.
    pub fn of_path(path: &Path) -> Option<Format> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "parquet" | "pq" => Some(Format::Parquet),
            "csv" => Some(Format::Csv),
            _ => None,
        }
    }

    /// The usual file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Parquet => "parquet",
            Format::Csv => "csv",
        }
    }
}

/// Writes `table` to `path` atomically in `format`.
pub fn write(table: &Table, path: &Path, format: Format) -> Result<()> {
    // A table can be 100 MB: what a killed writer of this file left is removed first.
    crate::store::remove_stale_temporaries(path);
    match format {
        Format::Parquet => parquet::write(table, path),
        Format::Csv => csv::write(table, path),
    }
}

/// Reads a table file, in the format its extension names (`.parquet`, `.pq` or `.csv`).
pub fn read(path: &Path) -> Result<Table> {
    match Format::of_path(path) {
        Some(Format::Parquet) => parquet::read(path),
        Some(Format::Csv) => csv::read(path),
        None => Err(Error::File {
            path: path.to_path_buf(),
            message: "unknown table format: the name must end in .parquet, .pq or .csv".into(),
        }),
    }
}

/// The first name in `names` that an earlier one repeats, found in linear time.
fn first_repeated(names: &[String]) -> Option<&str> {
    let mut seen = std::collections::HashSet::with_capacity(names.len());
    names.iter().find(|n| !seen.insert(n.as_str())).map(String::as_str)
}

/// Opens an input table file after checking it is a regular file within
/// [`crate::limits::TABLE_BYTES`]; returns it with its size.
fn open_input(path: &Path) -> Result<(std::fs::File, u64)> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    let meta = match std::fs::metadata(path) {
        Err(_) if crate::store::something_at(path) => return Err(refuse("is a link to nothing (dangling)".into())),
        Err(e) => return Err(Error::io(path, e)),
        Ok(m) => m,
    };
    if meta.is_dir() {
        return Err(refuse("is a directory, not a file".into()));
    }
    if !meta.is_file() {
        return Err(refuse("is not a regular file (a FIFO or a device)".into()));
    }
    if meta.len() > crate::limits::TABLE_BYTES {
        return Err(refuse(format!(
            "{} bytes: a table file may have at most {} bytes",
            meta.len(),
            crate::limits::TABLE_BYTES
        )));
    }
    Ok((std::fs::File::open(path).map_err(|e| Error::io(path, e))?, meta.len()))
}

/// Refuses a table of more rows, columns or cells than [`crate::limits`] allows, before it is
/// allocated; `path` names the file.
fn check_size(path: &Path, rows: u64, columns: u64) -> Result<()> {
    use crate::limits::{TABLE_CELLS, TABLE_COLUMNS, TABLE_ROWS};
    let message = if rows > TABLE_ROWS as u64 {
        format!("{rows} rows: a table may have at most {TABLE_ROWS}")
    } else if columns > TABLE_COLUMNS as u64 {
        format!("{columns} columns: a table may have at most {TABLE_COLUMNS}")
    } else if rows.saturating_mul(columns) > TABLE_CELLS as u64 {
        format!("{rows} rows × {columns} columns: a table may have at most {TABLE_CELLS} values")
    } else {
        return Ok(());
    };
    Err(Error::File { path: path.to_path_buf(), message })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A table with every type, missing values, and strings that need quoting in CSV.
    pub(crate) fn sample() -> Table {
        let mut t = Table::new();
        t.push("run", Column::Str(vec![Some("a,b".into()), Some("say \"hi\"".into()), None, Some(String::new())]))
            .unwrap();
        t.push("x", Column::Float(vec![0.1, f64::NAN, 1.0, -2.5e-300])).unwrap();
        t.push("n", Column::Int(vec![Some(1), None, Some(i64::MIN), Some(i64::MAX)])).unwrap();
        t.push("line", Column::Str(vec![Some("two\nlines".into()), Some("é ü".into()), Some("x".into()), None]))
            .unwrap();
        t
    }

    /// Equality with NaN equal to NaN (a float column's missing value).
    pub(crate) fn same(a: &Table, b: &Table) -> bool {
        a.names() == b.names()
            && a.columns().zip(b.columns()).all(|((_, x), (_, y))| match (x, y) {
                (Column::Float(x), Column::Float(y)) => {
                    x.len() == y.len()
                        && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits() || p.is_nan() && q.is_nan())
                }
                _ => x == y,
            })
    }

    #[test]
    fn columns_must_have_one_length_and_distinct_names() {
        let mut t = Table::new();
        t.push("a", Column::Float(vec![1.0, 2.0])).unwrap();
        assert!(t.push("b", Column::Int(vec![Some(1)])).unwrap_err().to_string().contains("'b' has 1 rows"));
        assert!(t.push("a", Column::Int(vec![None, None])).unwrap_err().to_string().contains("given twice"));
        assert_eq!((t.rows(), t.width()), (2, 1));
    }

    #[test]
    fn append_fills_missing_columns_and_refuses_other_types() {
        let mut a = Table::new();
        a.push("job", Column::Str(vec![Some("x".into())])).unwrap();
        a.push("score", Column::Float(vec![1.0])).unwrap();
        let mut b = Table::new();
        b.push("score", Column::Float(vec![2.0, 3.0])).unwrap();
        b.push("epochs", Column::Int(vec![Some(4), Some(5)])).unwrap();
        a.append(&b).unwrap();
        assert_eq!(a.names(), ["job", "score", "epochs"]);
        assert_eq!(a.column("job"), Some(&Column::Str(vec![Some("x".into()), None, None])));
        assert_eq!(a.column("epochs"), Some(&Column::Int(vec![None, Some(4), Some(5)])));
        assert_eq!(a.column("score"), Some(&Column::Float(vec![1.0, 2.0, 3.0])));
        let mut c = Table::new();
        c.push("score", Column::Str(vec![None])).unwrap();
        assert!(a.append(&c).unwrap_err().to_string().contains("'score' is float in one table and string"));
    }

    #[test]
    fn the_format_comes_from_the_extension() {
        assert_eq!(Format::of_path(Path::new("a/units.PARQUET")), Some(Format::Parquet));
        assert_eq!(Format::of_path(Path::new("u.csv")), Some(Format::Csv));
        assert_eq!(Format::of_path(Path::new("u.txt")), None);
        let e = read(Path::new("/nonexistent/u.txt")).unwrap_err().to_string();
        assert!(e.contains("u.txt") && e.contains(".parquet, .pq or .csv"), "{e}");
    }

    #[test]
    fn too_large_tables_are_refused_before_allocating() {
        let p = Path::new("t.csv");
        assert!(check_size(p, 3, 4).is_ok());
        let e = check_size(p, u64::MAX, 1).unwrap_err().to_string();
        assert!(e.starts_with("t.csv: ") && e.contains("rows"), "{e}");
        assert!(check_size(p, 1, u64::MAX).unwrap_err().to_string().contains("columns"));
        let n = crate::limits::TABLE_ROWS as u64;
        assert!(check_size(p, n, crate::limits::TABLE_COLUMNS as u64).unwrap_err().to_string().contains("values"));
    }
}
