//! CSV tables (RFC 4180): a header line of column names, then one line per row.
//!
//! Written: floats in Rust's shortest round-trip form (`0.1`, `1.0`, `1e-7`; `inf`), so they parse
//! back to the same double; a missing value (NaN, `None`) as an empty field; a string holding a
//! comma, a quote or a line break, or an empty string, in double quotes with quotes doubled;
//! lines end in `\n`.
//!
//! Read as pandas reads them: a column whose values all parse as integers is `int`, else one whose
//! values all parse as numbers is `float`, else `string`; an empty unquoted field is missing, a
//! column with only missing values is `float` (all NaN). A quoted empty field is the empty string.

use super::{Column, Table};
use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

/// Writes `table` to `path` atomically.
pub fn write(table: &Table, path: &Path) -> Result<()> {
    crate::store::write_atomic(path, |w| write_to(table, w))
}

/// Writes `table` as CSV to `w` (for `--out -`, standard output).
pub fn write_to(table: &Table, w: &mut impl Write) -> std::io::Result<()> {
    let names: Vec<String> = table.names().iter().map(|n| quoted(n)).collect();
    writeln!(w, "{}", names.join(","))?;
    let columns: Vec<&Column> = table.columns().map(|(_, c)| c).collect();
    let mut line = String::new();
    for r in 0..table.rows() {
        line.clear();
        for (i, c) in columns.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            match c {
                Column::Float(v) if v[r].is_nan() => {}
                Column::Float(v) => line.push_str(&format!("{:?}", v[r])),
                Column::Int(v) => line.push_str(&v[r].map_or(String::new(), |x| x.to_string())),
                Column::Str(v) => line.push_str(&v[r].as_deref().map_or(String::new(), quoted)),
            }
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// A field as written: in quotes when it holds a separator, a quote or a line break, or is empty
/// (so that it reads back as the empty string, not as missing).
fn quoted(s: &str) -> String {
    if s.is_empty() || s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The longest field read, in bytes: a number or a name is tens of bytes, and a line of one huge
/// field would otherwise be held whole before any check.
pub const MAX_FIELD: usize = 1 << 20;

/// Reads a CSV table. The file is read twice, streaming: once to check its shape and find each
/// column's type, once to parse the values, so memory holds the table and not the text.
pub fn read(path: &Path) -> Result<Table> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    let mut records = Records::open(path)?;
    // Fields past a record's allowed count are counted, not kept: memory stays within the caps
    // however long a line is.
    let most = crate::limits::TABLE_COLUMNS;
    let Some((_, header, width)) = records.next_record(most, true)? else {
        return Err(refuse("empty: a CSV table starts with a header line of column names".into()));
    };
    if width > most {
        // Refused as soon as seen: the rest of such a header is not read.
        return Err(refuse(format!("more than {most} columns: a table may have at most {most}")));
    }
    let names: Vec<String> = header.into_iter().map(|f| f.text).collect();
    if let Some(n) = super::first_repeated(&names) {
        return Err(refuse(format!("column '{n}' named twice in the header")));
    }
    let mut kinds = vec![Kind::Missing; names.len()];
    let mut rows = 0u64;
    while let Some((line, fields, count)) = records.next_record(names.len(), false)? {
        if blank(&fields, names.len()) {
            continue;
        }
        if count != names.len() {
            return Err(refuse(format!("line {line}: {count} fields, the header names {}", names.len())));
        }
        rows += 1;
        super::check_size(path, rows, names.len() as u64)?;
        for (k, f) in kinds.iter_mut().zip(&fields) {
            *k = k.widen(f);
        }
    }
    let rows = rows as usize;
    let mut columns: Vec<Column> = kinds
        .iter()
        .map(|k| match k {
            Kind::Missing | Kind::Float => Column::Float(Vec::with_capacity(rows)),
            Kind::Int => Column::Int(Vec::with_capacity(rows)),
            Kind::Str => Column::Str(Vec::with_capacity(rows)),
        })
        .collect();
    let mut records = Records::open(path)?;
    records.next_record(names.len(), false)?;
    while let Some((line, fields, _)) = records.next_record(names.len(), false)? {
        if blank(&fields, names.len()) {
            continue;
        }
        for ((c, f), name) in columns.iter_mut().zip(fields).zip(&names) {
            let bad = |kind: &str| refuse(format!("column '{name}', line {line}: '{}' is not {kind}", f.text));
            let missing = f.text.is_empty() && !f.quoted;
            match c {
                Column::Float(v) if missing => v.push(f64::NAN),
                Column::Float(v) => v.push(f.text.trim().parse().map_err(|_| bad("a number"))?),
                Column::Int(v) if missing => v.push(None),
                Column::Int(v) => v.push(Some(f.text.trim().parse().map_err(|_| bad("an integer"))?)),
                Column::Str(v) if missing => v.push(None),
                Column::Str(v) => v.push(Some(f.text)),
            }
        }
    }
    // Only a file changed between the two passes can give columns of other lengths.
    Table::from_parts(names, columns).map_err(|e| refuse(format!("changed while read ({e})")))
}

/// A blank line, skipped as pandas skips it (in a table of one column it is a missing value).
fn blank(fields: &[Field], width: usize) -> bool {
    width > 1 && fields.len() == 1 && fields[0].text.is_empty() && !fields[0].quoted
}

/// What a column's values allow, so far: the narrowest type holding them all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Missing,
    Int,
    Float,
    Str,
}

impl Kind {
    fn widen(self, f: &Field) -> Kind {
        if f.text.is_empty() {
            return if f.quoted { Kind::Str } else { self };
        }
        let t = f.text.trim();
        // Only what could still narrow the column is tried: a float column never becomes int.
        let this = if self == Kind::Str {
            Kind::Str
        } else if self != Kind::Float && t.parse::<i64>().is_ok() {
            Kind::Int
        } else if t.parse::<f64>().is_ok() {
            Kind::Float
        } else {
            Kind::Str
        };
        match (self, this) {
            (Kind::Missing, k) | (k, Kind::Missing) => k,
            (Kind::Str, _) | (_, Kind::Str) => Kind::Str,
            (Kind::Float, _) | (_, Kind::Float) => Kind::Float,
            (Kind::Int, Kind::Int) => Kind::Int,
        }
    }
}

/// One field: its text (quotes removed) and whether it was quoted.
#[derive(Debug)]
struct Field {
    text: String,
    quoted: bool,
}

/// The records of a CSV file, one at a time.
struct Records<'a> {
    path: &'a Path,
    input: BufReader<std::fs::File>,
    /// Line of the next byte (1-based).
    line: usize,
    /// A byte read ahead (after a closing quote, or a `\r`).
    peeked: Option<u8>,
}

impl<'a> Records<'a> {
    fn open(path: &'a Path) -> Result<Self> {
        let (file, _) = super::open_input(path)?;
        let mut r = Records { path, input: BufReader::new(file), line: 1, peeked: None };
        // A byte-order mark (spreadsheets write one) is not part of the first name.
        let start = r.input.fill_buf().map_err(|e| Error::io(path, e))?;
        if start.starts_with(b"\xEF\xBB\xBF") {
            r.input.consume(3);
        }
        Ok(r)
    }

    fn byte(&mut self) -> Result<Option<u8>> {
        if let Some(b) = self.peeked.take() {
            return Ok(Some(b));
        }
        // From the buffer itself: a `read` call per byte cost most of a read (bench data).
        let buf = self.input.fill_buf().map_err(|e| Error::io(self.path, e))?;
        let Some(&b) = buf.first() else { return Ok(None) };
        self.input.consume(1);
        Ok(Some(b))
    }

    fn refuse(&self, line: usize, what: &str) -> Error {
        Error::File { path: self.path.to_path_buf(), message: format!("line {line}: {what}") }
    }

    /// The next record with the line it starts on and its count of fields, of which the first
    /// `most` are kept; `None` at the end of the file. With `stop`, a record of more fields ends
    /// there, mid-line, with `most + 1` as its count (a header refused for its width).
    fn next_record(&mut self, most: usize, stop: bool) -> Result<Option<(usize, Vec<Field>, usize)>> {
        let start = self.line;
        let mut fields = Vec::new();
        let mut count = 0;
        let mut bytes = Vec::new();
        let mut quoted = false;
        let mut at_start = true;
        loop {
            let b = self.byte()?;
            match b {
                None if at_start && fields.is_empty() && bytes.is_empty() => return Ok(None),
                None => break,
                Some(b'"') if at_start => {
                    quoted = true;
                    self.read_quoted(&mut bytes)?;
                    at_start = false;
                    // After the closing quote: a separator, a line end or the end of the file.
                    if let Some(b) = self.byte()? {
                        if !matches!(b, b',' | b'\n' | b'\r') {
                            return Err(self.refuse(self.line, "text after a closing quote"));
                        }
                        self.peeked = Some(b);
                    }
                }
                Some(b'"') if !quoted => return Err(self.refuse(self.line, "a quote inside an unquoted field")),
                Some(b',') => {
                    count += 1;
                    if count <= most {
                        fields.push(self.field(std::mem::take(&mut bytes), quoted, start)?);
                    } else if stop {
                        return Ok(Some((start, fields, count)));
                    }
                    bytes.clear();
                    (quoted, at_start) = (false, true);
                }
                Some(b'\n') => {
                    self.line += 1;
                    break;
                }
                Some(b'\r') => {
                    match self.byte()? {
                        Some(b'\n') | None => {}
                        Some(other) => self.peeked = Some(other),
                    }
                    self.line += 1;
                    break;
                }
                Some(other) => {
                    bytes.push(other);
                    at_start = false;
                    if bytes.len() > MAX_FIELD {
                        return Err(self.refuse(self.line, &format!("a field longer than {} MiB", MAX_FIELD >> 20)));
                    }
                }
            }
        }
        count += 1;
        if count <= most {
            fields.push(self.field(bytes, quoted, start)?);
        }
        Ok(Some((start, fields, count)))
    }

    fn read_quoted(&mut self, bytes: &mut Vec<u8>) -> Result<()> {
        let start = self.line;
        loop {
            match self.byte()? {
                None => return Err(self.refuse(start, "a quoted field is never closed")),
                Some(b'"') => match self.byte()? {
                    Some(b'"') => bytes.push(b'"'),
                    other => {
                        self.peeked = other;
                        return Ok(());
                    }
                },
                Some(b) => {
                    if b == b'\n' {
                        self.line += 1;
                    }
                    bytes.push(b);
                    if bytes.len() > MAX_FIELD {
                        return Err(self.refuse(start, &format!("a field longer than {} MiB", MAX_FIELD >> 20)));
                    }
                }
            }
        }
    }

    fn field(&self, bytes: Vec<u8>, quoted: bool, line: usize) -> Result<Field> {
        let text = String::from_utf8(bytes).map_err(|_| self.refuse(line, "not UTF-8 text"))?;
        Ok(Field { text, quoted })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{same, sample};
    use super::*;

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("bfqi-table-csv-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn refused(text: &[u8]) -> String {
        let d = dir("bad");
        let p = d.join("bad.csv");
        std::fs::write(&p, text).unwrap();
        let e = read(&p).unwrap_err().to_string();
        std::fs::remove_dir_all(d).unwrap();
        assert!(e.starts_with(&p.display().to_string()), "names the file: {e}");
        e
    }

    #[test]
    fn quoting_missing_values_and_floats_are_written_as_pandas_reads_them() {
        let mut out = Vec::new();
        write_to(&sample(), &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(
            text,
            "run,x,n,line\n\"a,b\",0.1,1,\"two\nlines\"\n\"say \"\"hi\"\"\",,,é ü\n,1.0,-9223372036854775808,x\n\
             \"\",-2.5e-300,9223372036854775807,\n"
        );
    }

    #[test]
    fn round_trip_is_exact() {
        let d = dir("round");
        let p = d.join("t.csv");
        let mut t = sample();
        // Doubles that need all 17 digits, and the extremes.
        t = {
            let mut u = Table::new();
            for (n, c) in t.columns() {
                u.push(n, c.clone()).unwrap();
            }
            u.push("hard", Column::Float(vec![0.1 + 0.2, f64::MAX, f64::MIN_POSITIVE, -0.0])).unwrap();
            u.push("inf", Column::Float(vec![f64::INFINITY, f64::NEG_INFINITY, 1e21, 1e-7])).unwrap();
            u
        };
        write(&t, &p).unwrap();
        let back = read(&p).unwrap();
        assert!(same(&t, &back), "{t:?}\n{back:?}");
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn an_empty_table_keeps_its_names_and_reads_missing_only_columns_as_float() {
        let d = dir("empty");
        let p = d.join("t.csv");
        let mut t = Table::new();
        t.push("a", Column::Str(vec![])).unwrap();
        t.push("b b", Column::Int(vec![])).unwrap();
        write(&t, &p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "a,b b\n");
        let back = read(&p).unwrap();
        assert_eq!((back.names(), back.rows()), (t.names(), 0));
        assert_eq!(back.column("a"), Some(&Column::Float(vec![])));
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn types_are_inferred_per_column_and_line_ends_and_blank_lines_tolerated() {
        let d = dir("infer");
        let p = d.join("t.csv");
        std::fs::write(&p, "\u{feff}i,f,s,m\r\n1,2,x,\r\n\r\n-3,2.5,4,\n").unwrap();
        let t = read(&p).unwrap();
        assert_eq!(t.names(), ["i", "f", "s", "m"]);
        assert_eq!(t.column("i"), Some(&Column::Int(vec![Some(1), Some(-3)])));
        assert_eq!(t.column("f"), Some(&Column::Float(vec![2.0, 2.5])));
        assert_eq!(t.column("s"), Some(&Column::Str(vec![Some("x".into()), Some("4".into())])));
        assert!(matches!(t.column("m"), Some(Column::Float(v)) if v.iter().all(|x| x.is_nan())));
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn bad_files_are_refused_naming_file_and_line() {
        assert!(refused(b"").contains("empty"));
        assert!(refused(b"a,b\n1,2\n3\n").contains("line 3: 1 fields, the header names 2"));
        assert!(refused(b"a,b\n1,\"2\n").contains("line 2: a quoted field is never closed"));
        assert!(refused(b"a,b\n1,\"2\"x\n").contains("line 2: text after a closing quote"));
        assert!(refused(b"a,b\n1,2\"\n").contains("line 2: a quote inside an unquoted field"));
        assert!(refused(b"a,a\n1,2\n").contains("column 'a' named twice"));
        assert!(refused(b"a\n\xff\n").contains("line 2: not UTF-8 text"));
        // Too many fields on a line: counted exactly, though only the header's are kept.
        assert!(refused(b"a,b\n1,2,3,4,5\n").contains("line 2: 5 fields, the header names 2"));
        let long = [b"a\n".as_slice(), &vec![b'7'; MAX_FIELD + 1], b"\n"].concat();
        assert!(refused(&long).contains("line 2: a field longer than 1 MiB"));
        let quoted = [b"a\n\"".as_slice(), &vec![b'7'; MAX_FIELD + 1], b"\"\n"].concat();
        assert!(refused(&quoted).contains("line 2: a field longer than 1 MiB"));
        let d = dir("dir");
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn the_widest_header_reads_and_a_wider_one_is_refused_early() {
        let most = crate::limits::TABLE_COLUMNS;
        let d = dir("wide");
        let p = d.join("t.csv");
        let line = |n: usize, f: &dyn Fn(usize) -> String| (0..n).map(f).collect::<Vec<_>>().join(",");
        // The widest table allowed: its name check and table were quadratic (40,000 columns took 34 s).
        std::fs::write(&p, format!("{}\n{}\n", line(most, &|i| format!("c{i}")), line(most, &|i| i.to_string())))
            .unwrap();
        let t = read(&p).unwrap();
        assert_eq!((t.width(), t.rows()), (most, 1));
        assert_eq!(t.column("c99999"), Some(&Column::Int(vec![Some(99_999)])));
        // One column more is refused, without reading the rest of the line into fields.
        std::fs::write(&p, format!("{}\n", line(most + 1, &|i| format!("c{i}")))).unwrap();
        let e = read(&p).unwrap_err().to_string();
        assert!(e.contains(&format!("more than {most} columns")), "{e}");
        // A name repeated far apart is still found.
        std::fs::write(&p, format!("{},c0\n", line(1000, &|i| format!("c{i}")))).unwrap();
        assert!(read(&p).unwrap_err().to_string().contains("column 'c0' named twice"));
        std::fs::remove_dir_all(d).unwrap();
    }
}
