//! CSV tables: the encoder of every CSV nusselt writes and the reader of
//! the ones it reads, both through the `csv` crate (its only user).
//!
//! Owns: the dialect (comma-separated, `\n` line ends, RFC 4180 quoting: a
//! field is quoted only when it holds a comma, a quote or a line break, and
//! a quote inside it is doubled), the number formats a row struct gives its
//! columns (`#[serde(serialize_with = "csv::sci::<9, _>")]` and the like:
//! [`plain`], [`fixed`], [`sci`], [`sci_or_empty`]), and reading a table by
//! its header ([`read`]).
//!
//! Invariants:
//! - [`encode`] writes its header even when there is no row; a row struct
//!   lists its fields in the header's order (the header is the caller's,
//!   so a table with no rows still has one).
//! - [`read`] finds columns by name (any order, more columns ignored),
//!   trims spaces around fields, skips blank lines, and reports anything it
//!   cannot use as one [`Error::Data`] line naming the file and the line of
//!   the file (not the record) it is on.

use std::fmt::Display;
use std::path::Path;

use serde::de::DeserializeOwned;
use serde::{Serialize, Serializer};

use crate::error::{Error, Result};

/// The CSV bytes of `rows` under the header `header`: one record per row,
/// the row's fields in order.
pub fn encode<R: Serialize>(header: &[&str], rows: impl IntoIterator<Item = R>) -> Result<Vec<u8>> {
    let fail = |e: &dyn Display| Error::encode("CSV", e);
    let mut writer = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(Vec::new());
    writer.write_record(header).map_err(|e| fail(&e))?;
    for row in rows {
        writer.serialize(row).map_err(|e| fail(&e))?;
    }
    writer.into_inner().map_err(|e| fail(e.error()))
}

/// A float as Rust's `{}` prints it: the shortest text that reads back
/// to the same value, never in exponent form.
pub fn plain<S: Serializer>(value: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.collect_str(value)
}

/// A float with `DIGITS` digits after the point (`{:.DIGITS$}`).
pub fn fixed<const DIGITS: usize, S: Serializer>(
    value: &f64,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    s.collect_str(&format_args!("{value:.DIGITS$}"))
}

/// A float in exponent form with `DIGITS` digits after the point
/// (`{:.DIGITS$e}`: `1.500e-3`).
pub fn sci<const DIGITS: usize, S: Serializer>(
    value: &f64,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    s.collect_str(&format_args!("{value:.DIGITS$e}"))
}

/// [`sci`] of a value that may be missing: an empty field when it is.
pub fn sci_or_empty<const DIGITS: usize, S: Serializer>(
    value: &Option<f64>,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    match value {
        Some(v) => sci::<DIGITS, S>(v, s),
        None => s.serialize_none(),
    }
}

/// Reads the CSV file `path`: a header naming at least `columns`, then one
/// record per line, each deserialized by column name as an `R` and turned
/// into a `T` by `convert` (whose message is reported with the line).
pub fn read<R, T>(
    path: &Path,
    columns: &[&str],
    mut convert: impl FnMut(R) -> std::result::Result<T, String>,
) -> Result<Vec<T>>
where
    R: DeserializeOwned,
{
    let bytes = std::fs::read(path).map_err(|e| Error::input(path, e))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(bytes.as_slice());
    let header = reader
        .headers()
        .map_err(|e| failure(path, &bytes, &e, &csv::StringRecord::new(), None))?
        .clone();
    if header.iter().all(str::is_empty) {
        return Err(Error::data(path, "empty file: a header line is needed"));
    }
    if let Some(name) = columns.iter().find(|&&n| !header.iter().any(|h| h == n)) {
        return Err(Error::data(
            path,
            format!("no column '{name}' in the header"),
        ));
    }
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| failure(path, &bytes, &e, &header, None))?;
        // A line of spaces: one empty field once trimmed.
        if record.len() == 1 && record[0].is_empty() {
            continue;
        }
        let row: R = record
            .deserialize(Some(&header))
            .map_err(|e| failure(path, &bytes, &e, &header, Some(&record)))?;
        let line = record.position().map_or(0, |p| line_of(&bytes, p));
        rows.push(convert(row).map_err(|m| Error::data(path, format!("line {line}: {m}")))?);
    }
    Ok(rows)
}

/// The line of the file on which the record at `position` starts.
///
/// The `csv` crate reports, for the first record after blank lines, the
/// line of the first blank line (BurntSushi/rust-csv#208): the line
/// breaks it skipped from there are counted here.
fn line_of(bytes: &[u8], position: &csv::Position) -> u64 {
    let start = usize::try_from(position.byte()).unwrap_or(usize::MAX);
    let skipped = bytes
        .get(start..)
        .unwrap_or_default()
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .filter(|&&b| b == b'\n')
        .count();
    position.line() + skipped as u64
}

/// `error` of reading `path`, as one line naming the line of the file and,
/// when known, the column (by its name in `header`) and its text in
/// `record`.
fn failure(
    path: &Path,
    bytes: &[u8],
    error: &csv::Error,
    header: &csv::StringRecord,
    record: Option<&csv::StringRecord>,
) -> Error {
    let column = |field: u64| {
        let k = usize::try_from(field).unwrap_or(usize::MAX);
        let name = header
            .get(k)
            .map_or(format!("{}", field.saturating_add(1)), |h| format!("'{h}'"));
        match record.and_then(|r| r.get(k)) {
            Some(text) => format!("column {name} ({text:?})"),
            None => format!("column {name}"),
        }
    };
    let what = match error.kind() {
        csv::ErrorKind::Utf8 { err, .. } => {
            format!("{}: not UTF-8 text", column(err.field() as u64))
        }
        csv::ErrorKind::Deserialize { err, .. } => match (err.kind(), err.field(), record) {
            (csv::DeserializeErrorKind::UnexpectedEndOfRow, _, Some(r)) => {
                let fields = if r.len() == 1 { "field" } else { "fields" };
                format!("{} {fields}, the header has {}", r.len(), header.len())
            }
            (kind, Some(field), _) => format!("{}: {kind}", column(field)),
            (kind, None, _) => kind.to_string(),
        },
        _ => error.to_string(),
    };
    match error.position() {
        Some(p) => Error::data(path, format!("line {}: {what}", line_of(bytes, p))),
        None => Error::data(path, what),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, serde::Deserialize, Debug, PartialEq)]
    struct Row {
        name: String,
        #[serde(serialize_with = "sci::<3, _>")]
        value: f64,
        #[serde(serialize_with = "sci_or_empty::<2, _>")]
        spread: Option<f64>,
        #[serde(serialize_with = "fixed::<2, _>")]
        seconds: f64,
        #[serde(serialize_with = "plain")]
        x: f64,
    }

    const HEADER: [&str; 5] = ["name", "value", "spread", "seconds", "x"];

    fn write(dir: &Path, name: &str, text: &[u8]) -> std::path::PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn numbers_keep_their_formats() {
        let rows = [Row {
            name: "a".into(),
            value: 1.5e-3,
            spread: None,
            seconds: 2.0,
            x: 0.1,
        }];
        let text = String::from_utf8(encode(&HEADER, &rows).unwrap()).unwrap();
        assert_eq!(text, "name,value,spread,seconds,x\na,1.500e-3,,2.00,0.1\n");
        let none: [Row; 0] = [];
        assert_eq!(
            encode(&HEADER, &none).unwrap(),
            b"name,value,spread,seconds,x\n"
        );
    }

    #[test]
    fn text_with_commas_quotes_and_line_breaks_round_trips() {
        let name = "wall, \"north\"\nside";
        let rows = [Row {
            name: name.into(),
            value: 1.0,
            spread: Some(0.5),
            seconds: 1.0,
            x: -2.5,
        }];
        let bytes = encode(&HEADER, &rows).unwrap();
        assert!(bytes.starts_with(b"name,value,spread,seconds,x\n\"wall, \"\"north\"\"\nside\","));
        let dir = tempfile::tempdir().unwrap();
        let path = write(dir.path(), "t.csv", &bytes);
        let back: Vec<Row> = read(&path, &HEADER, Ok).unwrap();
        assert_eq!(back, rows);
    }

    #[test]
    fn reads_by_name_skipping_blank_lines() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            dir.path(),
            "t.csv",
            b" x , extra,name,value,spread,seconds\n\n1, q ,a,2,,3\n   \n4,q,b,5,6,7,more\n",
        );
        let back: Vec<Row> = read(&path, &HEADER, Ok).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(
            (back[0].x, back[0].name.as_str(), back[0].spread),
            (1.0, "a", None)
        );
        assert_eq!((back[1].x, back[1].spread), (4.0, Some(6.0)));
    }

    #[test]
    fn errors_name_the_file_and_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let message = |text: &[u8]| {
            let path = write(dir.path(), "bad.csv", text);
            read::<Row, Row>(&path, &HEADER, Ok)
                .unwrap_err()
                .to_string()
        };
        let head = "name,value,spread,seconds,x\n";
        // After blank lines, the line is still the file's.
        let m = message(format!("{head}a,1,,1,1\n\n\nb,oops,,1,1\n").as_bytes());
        assert!(m.contains("bad.csv") && m.contains("line 5"), "{m}");
        assert!(m.contains("column 'value' (\"oops\")"), "{m}");
        let m = message(format!("{head}a,1,,1\n").as_bytes());
        assert!(m.contains("line 2: 4 fields, the header has 5"), "{m}");
        let m = message(b"name,value\n");
        assert!(m.contains("no column 'spread'"), "{m}");
        let m = message(b"");
        assert!(m.contains("empty file"), "{m}");
        // An unclosed quote runs to the end of the file: one field.
        let m = message(format!("{head}a,1,,1,1\n\"b,1,,1,1\n").as_bytes());
        assert!(m.contains("line 3: 1 field, the header has 5"), "{m}");
        let mut latin1 = format!("{head}a,1,,1,1\n").into_bytes();
        latin1.extend_from_slice(b"\xe9,1,,1,1\n");
        let m = message(&latin1);
        assert!(m.contains("line 3") && m.contains("column 'name'"), "{m}");
        // The converter's refusal comes with the line too.
        let path = write(dir.path(), "c.csv", format!("{head}a,1,,1,1\n").as_bytes());
        let e = read::<Row, Row>(&path, &HEADER, |_| Err("no good".into())).unwrap_err();
        assert!(e.to_string().ends_with("c.csv: line 2: no good"), "{e}");
    }
}
