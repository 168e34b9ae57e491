//! Parquet tables, through the `parquet` crate's low-level column API (no Arrow).
//!
//! Written: one optional column per table column — `float` as DOUBLE (NaN written as null),
//! `int` as INT64, `string` as BYTE_ARRAY annotated UTF-8 — snappy-compressed, in row groups of
//! at most [`ROW_GROUP`] rows. pandas reads them as float64, Int64-or-float64 and object columns.
//!
//! Read: what the writer writes, and the flat columns pandas (pyarrow) writes for float32, int8–
//! int32, uint8–uint32, bool (read as 0 / 1) and string; a null float reads as NaN. Nested
//! columns, timestamps, decimals, uint64 and raw binary are refused, naming the column.

use super::{Column, Table};
use crate::error::{Error, Result};
use parquet::basic::{Compression, ConvertedType, LogicalType, Repetition, Type as PhysicalType};
use parquet::column::reader::{ColumnReader, ColumnReaderImpl};
use parquet::column::writer::ColumnWriter;
use parquet::data_type::{ByteArray, DataType};
use parquet::file::properties::WriterProperties;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::{ColumnDescriptor, Type};
use std::path::Path;
use std::sync::Arc;

/// Rows per row group written.
pub const ROW_GROUP: usize = 1 << 20;

/// Writes `table` to `path` atomically.
pub fn write(table: &Table, path: &Path) -> Result<()> {
    let schema = schema(table).map_err(|e| Error::File { path: path.to_path_buf(), message: e.to_string() })?;
    crate::store::write_atomic(path, |w| write_to(table, schema, w, ROW_GROUP).map_err(std::io::Error::other))
}

/// The file's schema: one optional column per table column.
fn schema(table: &Table) -> parquet::errors::Result<Arc<Type>> {
    let fields = table
        .columns()
        .map(|(name, c)| {
            let (physical, logical) = match c {
                Column::Float(_) => (PhysicalType::DOUBLE, None),
                Column::Int(_) => (PhysicalType::INT64, None),
                Column::Str(_) => (PhysicalType::BYTE_ARRAY, Some(LogicalType::String)),
            };
            Type::primitive_type_builder(name, physical)
                .with_repetition(Repetition::OPTIONAL)
                .with_logical_type(logical)
                .build()
                .map(Arc::new)
        })
        .collect::<parquet::errors::Result<Vec<_>>>()?;
    Ok(Arc::new(Type::group_type_builder("schema").with_fields(fields).build()?))
}

/// Writes `table` to `w` in row groups of `group` rows.
fn write_to(
    table: &Table,
    schema: Arc<Type>,
    w: impl std::io::Write + Send,
    group: usize,
) -> parquet::errors::Result<()> {
    let props = Arc::new(
        WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_created_by(format!("bfqi-ga {}", env!("CARGO_PKG_VERSION")))
            .build(),
    );
    let mut writer = SerializedFileWriter::new(w, schema, props)?;
    let columns: Vec<&Column> = table.columns().map(|(_, c)| c).collect();
    let mut start = 0;
    // A table without rows still gets its (empty) row group, so readers see its columns' types.
    while start < table.rows() || start == 0 {
        let end = (start + group).min(table.rows());
        let mut group = writer.next_row_group()?;
        for c in &columns {
            let mut col = group.next_column()?.expect("one column writer per schema field");
            match (col.untyped(), c) {
                (ColumnWriter::DoubleColumnWriter(w), Column::Float(v)) => {
                    let v = &v[start..end];
                    let values: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
                    let levels: Vec<i16> = v.iter().map(|x| i16::from(!x.is_nan())).collect();
                    w.write_batch(&values, Some(&levels), None)?;
                }
                (ColumnWriter::Int64ColumnWriter(w), Column::Int(v)) => {
                    let v = &v[start..end];
                    let values: Vec<i64> = v.iter().flatten().copied().collect();
                    let levels: Vec<i16> = v.iter().map(|x| i16::from(x.is_some())).collect();
                    w.write_batch(&values, Some(&levels), None)?;
                }
                (ColumnWriter::ByteArrayColumnWriter(w), Column::Str(v)) => {
                    let v = &v[start..end];
                    let values: Vec<ByteArray> = v.iter().flatten().map(|s| ByteArray::from(s.as_str())).collect();
                    let levels: Vec<i16> = v.iter().map(|x| i16::from(x.is_some())).collect();
                    w.write_batch(&values, Some(&levels), None)?;
                }
                _ => unreachable!("the schema gives each column its writer's type"),
            }
            col.close()?;
        }
        group.close()?;
        if end == table.rows() {
            break;
        }
        start = end;
    }
    writer.close()?;
    Ok(())
}

/// How a file's column is read into a table column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Read {
    Double,
    Float32,
    Int64,
    Int32 { unsigned: bool },
    Bool,
    Utf8,
}

/// How column `c` is read, or why it cannot be.
fn plan(c: &ColumnDescriptor) -> std::result::Result<Read, String> {
    if c.max_rep_level() > 0 || c.path().parts().len() != 1 {
        return Err("is nested (a list, map or struct): only flat columns can be read".into());
    }
    let logical = c.logical_type_ref();
    let int = |bits: i8| match logical {
        None => Some(true),
        Some(LogicalType::Integer(t)) if t.bit_width <= bits => Some(t.is_signed),
        _ => None,
    };
    let read = match c.physical_type() {
        PhysicalType::DOUBLE if logical.is_none() => Read::Double,
        PhysicalType::FLOAT if logical.is_none() => Read::Float32,
        PhysicalType::INT64 if int(64) == Some(true) => Read::Int64,
        PhysicalType::INT32 => match int(32) {
            Some(signed) => Read::Int32 { unsigned: !signed },
            None => return Err(format!("is INT32 {logical:?}: only plain integers can be read")),
        },
        PhysicalType::BOOLEAN => Read::Bool,
        PhysicalType::BYTE_ARRAY
            if matches!(logical, Some(LogicalType::String)) || c.converted_type() == ConvertedType::UTF8 =>
        {
            Read::Utf8
        }
        other => {
            return Err(format!(
                "is {other}{}: readable are double, float, int64, int32 and smaller integers, bool and UTF-8 strings",
                logical.map_or(String::new(), |l| format!(" ({l:?})"))
            ));
        }
    };
    Ok(read)
}

/// Reads a Parquet table (see the module's documentation for the column types read).
pub fn read(path: &Path) -> Result<Table> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    let (file, _) = super::open_input(path)?;
    let reader = SerializedFileReader::new(file).map_err(|e| refuse(format!("not a readable Parquet file ({e})")))?;
    let meta = reader.metadata();
    let schema = meta.file_metadata().schema_descr();
    let width = schema.num_columns();
    let mut rows: u64 = 0;
    for g in meta.row_groups() {
        let n = u64::try_from(g.num_rows()).map_err(|_| refuse("a row group with a negative row count".into()))?;
        rows = rows.saturating_add(n);
    }
    super::check_size(path, rows, width as u64)?;
    let rows = rows as usize;
    let mut names = Vec::with_capacity(width);
    let mut plans = Vec::with_capacity(width);
    let mut columns = Vec::with_capacity(width);
    for j in 0..width {
        let c = schema.column(j);
        let name = c.name().to_string();
        let read = plan(&c).map_err(|why| refuse(format!("column '{name}' {why}")))?;
        columns.push(match read {
            Read::Double | Read::Float32 => Column::Float(Vec::with_capacity(rows)),
            Read::Int64 | Read::Int32 { .. } | Read::Bool => Column::Int(Vec::with_capacity(rows)),
            Read::Utf8 => Column::Str(Vec::with_capacity(rows)),
        });
        names.push(name);
        plans.push(read);
    }
    if let Some(name) = super::first_repeated(&names) {
        return Err(refuse(format!("column '{name}' named twice")));
    }
    for (g, group_meta) in meta.row_groups().iter().enumerate() {
        let group = reader.get_row_group(g).map_err(|e| refuse(format!("row group {g}: {e}")))?;
        let n = group_meta.num_rows() as usize;
        for j in 0..width {
            let name = &names[j];
            let bad = |e: String| refuse(format!("column '{name}', row group {g}: {e}"));
            let col = group.get_column_reader(j).map_err(|e| bad(e.to_string()))?;
            let got = match (col, plans[j], &mut columns[j]) {
                (ColumnReader::DoubleColumnReader(r), _, Column::Float(v)) => chunk(r, n, v, |x| x, f64::NAN),
                (ColumnReader::FloatColumnReader(r), _, Column::Float(v)) => chunk(r, n, v, f64::from, f64::NAN),
                (ColumnReader::Int64ColumnReader(r), _, Column::Int(v)) => chunk(r, n, v, Some, None),
                (ColumnReader::Int32ColumnReader(r), Read::Int32 { unsigned }, Column::Int(v)) => {
                    chunk(r, n, v, |x| Some(if unsigned { i64::from(x as u32) } else { i64::from(x) }), None)
                }
                (ColumnReader::BoolColumnReader(r), _, Column::Int(v)) => chunk(r, n, v, |x| Some(i64::from(x)), None),
                (ColumnReader::ByteArrayColumnReader(r), _, Column::Str(v)) => {
                    let start = v.len();
                    let mut raw: Vec<Option<ByteArray>> = Vec::with_capacity(n);
                    let got = chunk(r, n, &mut raw, Some, None);
                    for (i, b) in raw.into_iter().enumerate() {
                        let s = b.map(|b| String::from_utf8(b.data().to_vec())).transpose();
                        v.push(s.map_err(|_| bad(format!("row {} is not UTF-8 text", start + i)))?);
                    }
                    got
                }
                _ => unreachable!("the plan gives each column its reader's type"),
            };
            got.map_err(bad)?;
        }
    }
    Table::from_parts(names, columns).map_err(|e| refuse(e.to_string()))
}

/// Reads the `rows` values of one column chunk into `out`, each value through `convert`, a null as
/// `null`; an error says what is wrong (fewer values than the row group's rows).
fn chunk<T: DataType, O>(
    mut r: ColumnReaderImpl<T>,
    rows: usize,
    out: &mut Vec<O>,
    convert: impl Fn(T::T) -> O,
    null: O,
) -> std::result::Result<(), String>
where
    O: Clone,
{
    const BATCH: usize = 65_536;
    let mut values = Vec::new();
    let mut levels = Vec::new();
    let mut done = 0;
    while done < rows {
        values.clear();
        levels.clear();
        let want = BATCH.min(rows - done);
        let (records, _, _) = r.read_records(want, Some(&mut levels), None, &mut values).map_err(|e| e.to_string())?;
        if records == 0 {
            return Err(format!("{done} values, where the row group has {rows} rows"));
        }
        if levels.is_empty() {
            // A required column: no definition levels, every record a value.
            out.extend(values.drain(..).map(&convert));
        } else {
            let mut vals = values.drain(..);
            for &l in &levels[..records] {
                match l {
                    0 => out.push(null.clone()),
                    _ => out.push(convert(vals.next().ok_or("fewer values than its definition levels say")?)),
                }
            }
        }
        done += records;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::tests::{same, sample};
    use super::*;
    use parquet::data_type::{BoolType, FloatType, Int32Type};

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("bfqi-table-pq-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn round_trip_is_exact_across_row_groups() {
        let d = dir("round");
        let p = d.join("t.parquet");
        let t = sample();
        write(&t, &p).unwrap();
        assert!(same(&t, &read(&p).unwrap()));
        // Several row groups, the last one short.
        let f = std::fs::File::create(&p).unwrap();
        write_to(&t, schema(&t).unwrap(), f, 3).unwrap();
        let r = SerializedFileReader::new(std::fs::File::open(&p).unwrap()).unwrap();
        assert_eq!(r.metadata().num_row_groups(), 2);
        assert!(same(&t, &read(&p).unwrap()));
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn an_empty_table_keeps_its_names_and_types() {
        let d = dir("empty");
        let p = d.join("t.parquet");
        let mut t = Table::new();
        t.push("a", Column::Str(vec![])).unwrap();
        t.push("b", Column::Int(vec![])).unwrap();
        t.push("c", Column::Float(vec![])).unwrap();
        write(&t, &p).unwrap();
        assert_eq!(read(&p).unwrap(), t);
        std::fs::remove_dir_all(d).unwrap();
    }

    /// A file of pandas-like columns: required float32, nullable int32 and uint32, bool.
    fn pandas_like(path: &Path) {
        let field = |name: &str, t: PhysicalType, rep: Repetition, logical: Option<LogicalType>| {
            Arc::new(
                Type::primitive_type_builder(name, t).with_repetition(rep).with_logical_type(logical).build().unwrap(),
            )
        };
        let fields = vec![
            field("f32", PhysicalType::FLOAT, Repetition::REQUIRED, None),
            field("i32", PhysicalType::INT32, Repetition::OPTIONAL, None),
            field("u32", PhysicalType::INT32, Repetition::OPTIONAL, Some(LogicalType::integer(32, false))),
            field("ok", PhysicalType::BOOLEAN, Repetition::OPTIONAL, None),
        ];
        let schema = Arc::new(Type::group_type_builder("schema").with_fields(fields).build().unwrap());
        let f = std::fs::File::create(path).unwrap();
        let mut w = SerializedFileWriter::new(f, schema, Arc::new(WriterProperties::builder().build())).unwrap();
        let mut g = w.next_row_group().unwrap();
        let mut c = g.next_column().unwrap().unwrap();
        c.typed::<FloatType>().write_batch(&[0.5, -1.25, 3.0], None, None).unwrap();
        c.close().unwrap();
        let mut c = g.next_column().unwrap().unwrap();
        c.typed::<Int32Type>().write_batch(&[7, -8], Some(&[1, 0, 1]), None).unwrap();
        c.close().unwrap();
        let mut c = g.next_column().unwrap().unwrap();
        c.typed::<Int32Type>().write_batch(&[-1i32, 2, 3], Some(&[1, 1, 1]), None).unwrap();
        c.close().unwrap();
        let mut c = g.next_column().unwrap().unwrap();
        c.typed::<BoolType>().write_batch(&[true, false], Some(&[1, 1, 0]), None).unwrap();
        c.close().unwrap();
        g.close().unwrap();
        w.close().unwrap();
    }

    #[test]
    fn pandas_column_types_are_read() {
        let d = dir("pandas");
        let p = d.join("t.parquet");
        pandas_like(&p);
        let t = read(&p).unwrap();
        assert_eq!(t.column("f32"), Some(&Column::Float(vec![0.5, -1.25, 3.0])));
        assert_eq!(t.column("i32"), Some(&Column::Int(vec![Some(7), None, Some(-8)])));
        assert_eq!(t.column("u32"), Some(&Column::Int(vec![Some(u32::MAX as i64), Some(2), Some(3)])));
        assert_eq!(t.column("ok"), Some(&Column::Int(vec![Some(1), Some(0), None])));
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn bad_files_are_refused_naming_file_and_column() {
        let d = dir("bad");
        let p = d.join("t.parquet");
        std::fs::write(&p, b"a,b\n1,2\n").unwrap();
        let e = read(&p).unwrap_err().to_string();
        assert!(e.starts_with(&p.display().to_string()) && e.contains("not a readable Parquet file"), "{e}");
        // Cut short: the footer is gone.
        write(&sample(), &p).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        assert!(read(&p).unwrap_err().to_string().contains("not a readable Parquet file"));
        // A timestamp column.
        let ts = Type::primitive_type_builder("when", PhysicalType::INT64)
            .with_repetition(Repetition::OPTIONAL)
            .with_logical_type(Some(LogicalType::Timestamp(parquet::basic::TimestampType {
                is_adjusted_to_u_t_c: true,
                unit: parquet::basic::TimeUnit::MILLIS,
            })))
            .build()
            .unwrap();
        let schema = Arc::new(Type::group_type_builder("schema").with_fields(vec![Arc::new(ts)]).build().unwrap());
        let f = std::fs::File::create(&p).unwrap();
        let mut w = SerializedFileWriter::new(f, schema, Arc::new(WriterProperties::builder().build())).unwrap();
        let mut g = w.next_row_group().unwrap();
        let mut c = g.next_column().unwrap().unwrap();
        c.typed::<parquet::data_type::Int64Type>().write_batch(&[5], Some(&[1]), None).unwrap();
        c.close().unwrap();
        g.close().unwrap();
        w.close().unwrap();
        let e = read(&p).unwrap_err().to_string();
        assert!(e.contains("column 'when' is INT64") && e.contains("readable are"), "{e}");
        std::fs::remove_dir_all(d).unwrap();
    }
}
