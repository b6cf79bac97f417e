//! The one batch loop every row-wise command shares: read a CSV header and rows, find the
//! columns by name, compute each row, and write the input echoed followed by the results
//! and an `error` column. A bad row never stops the run; it yields a row whose result
//! columns are empty and whose `error` names the field or the failing step.
//!
//! The single-pose form of a command goes through the same row code: its flags become a
//! one-row table with the same column names, so both forms print identical lines.

use crate::columns::{check_field, FieldError, Row};
use std::io::{Read, Write};
use thiserror::Error;

/// The name of the column that carries a row's error message (empty when fine).
pub const ERROR_COLUMN: &str = "error";
/// Prefix given to an echoed input column whose name a result column also uses (for
/// instance `x_mm` when the output of `ik` is fed to `fk`).
pub const ECHO_PREFIX: &str = "in_";

/// One row-wise calculation: what it reads, what it writes, and how.
pub trait Calculation {
    /// What a row's calculation fails with (its message goes to the `error` column).
    type Error: std::error::Error + From<FieldError>;
    /// The command name, for messages.
    fn name(&self) -> &'static str;
    /// Columns every input must have.
    fn required_columns(&self) -> Vec<&'static str>;
    /// Columns that are read when present.
    fn optional_columns(&self) -> Vec<&'static str> {
        Vec::new()
    }
    /// Result columns, written after the echoed input and before `error`.
    fn result_columns(&self) -> Vec<&'static str>;
    /// The result fields of one row (one per result column), or what was wrong.
    fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, Self::Error>;
}

/// Why a batch (or single-form) run failed as a whole; `E` is the calculation's row error.
#[derive(Debug, Error)]
pub enum BatchError<E: std::error::Error> {
    #[error("{name}: the input is empty; expected a CSV header with the columns {}", required.join(","))]
    EmptyInput {
        name: &'static str,
        required: Vec<&'static str>,
    },
    #[error("{name}: the input has no column \"{column}\" (required: {})", required.join(","))]
    MissingColumn {
        name: &'static str,
        column: &'static str,
        required: Vec<&'static str>,
    },
    #[error("{name}: the input has the column \"{column}\" more than once")]
    RepeatedColumn {
        name: &'static str,
        column: &'static str,
    },
    #[error("{name}: cannot read the CSV header: {source}")]
    Header {
        name: &'static str,
        source: csv::Error,
    },
    #[error("{name}: cannot read row {row}: {source}")]
    Read {
        name: &'static str,
        row: usize,
        source: csv::Error,
    },
    #[error("{name}: cannot write the output: {source}")]
    Write {
        name: &'static str,
        source: csv::Error,
    },
    #[error("{name}: cannot write the output: {source}")]
    Flush {
        name: &'static str,
        source: std::io::Error,
    },
    /// The single form: a flag's values.
    #[error(transparent)]
    Flag(#[from] FlagValueError),
    /// The single form: the calculation failed.
    #[error(transparent)]
    Row(E),
    /// A calculation that broke its contract of one field per result column.
    #[error("{name}: internal error: {given} result fields for {width} columns")]
    Width {
        name: &'static str,
        given: usize,
        width: usize,
    },
}

/// A flag of the single form whose value does not fill its columns.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum FlagValueError {
    #[error("{flag}: expected {what} ({}), got {given}", columns.join(","))]
    Count {
        flag: &'static str,
        what: String,
        columns: Vec<&'static str>,
        given: usize,
    },
    #[error("{flag}: {error}")]
    Field {
        flag: &'static str,
        error: FieldError,
    },
}

/// What is wrong with one row of a batch, for its `error` column.
#[derive(Debug, Error)]
enum RowProblem<E: std::error::Error> {
    #[error("has {fields} fields, the header has {header}")]
    FieldCount { fields: usize, header: usize },
    #[error("unreadable: {0}")]
    Unreadable(csv::Error),
    #[error(transparent)]
    Calculation(E),
    #[error("{name}: internal error: {given} result fields for {width} columns")]
    Width {
        name: &'static str,
        given: usize,
        width: usize,
    },
}

/// Counts of a batch run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchSummary {
    /// Data rows read.
    pub rows: usize,
    /// Rows whose `error` column is filled.
    pub bad_rows: usize,
}

/// The output header: the input columns (renamed with [`ECHO_PREFIX`] where they collide
/// with a result column), the result columns and `error`.
fn output_header<C: Calculation + ?Sized>(calc: &C, input: &[String]) -> Vec<String> {
    let results = calc.result_columns();
    let collides = |name: &str| name == ERROR_COLUMN || results.contains(&name);
    let mut header: Vec<String> = input
        .iter()
        .map(|c| {
            if collides(c) {
                format!("{ECHO_PREFIX}{c}")
            } else {
                c.clone()
            }
        })
        .collect();
    header.extend(results.iter().map(|c| c.to_string()));
    header.push(ERROR_COLUMN.to_string());
    header
}

/// Checks that the required columns are present and no read column is ambiguous.
fn check_header<C: Calculation + ?Sized>(
    calc: &C,
    header: &[String],
) -> Result<(), BatchError<C::Error>> {
    let name = calc.name();
    let required = calc.required_columns();
    if header.iter().all(|h| h.is_empty()) {
        return Err(BatchError::EmptyInput { name, required });
    }
    for &column in &required {
        if !header.iter().any(|h| h == column) {
            return Err(BatchError::MissingColumn {
                name,
                column,
                required,
            });
        }
    }
    for &column in required.iter().chain(calc.optional_columns().iter()) {
        if header.iter().filter(|h| *h == column).count() > 1 {
            return Err(BatchError::RepeatedColumn { name, column });
        }
    }
    Ok(())
}

/// The output fields of one row: the echo padded or cut to the header's width, the
/// results (empty on error) and the error message (`row N: ...`, empty when fine).
fn output_row<C: Calculation + ?Sized>(
    calc: &C,
    header: &[String],
    fields: &[String],
    row_number: usize,
    pre_error: Option<RowProblem<C::Error>>,
) -> (Vec<String>, bool) {
    let width = calc.result_columns().len();
    let result = match pre_error {
        Some(e) => Err(e),
        None => calc
            .compute(&Row::new(header, fields))
            .map_err(RowProblem::Calculation)
            .and_then(|r| {
                check_width(r, width).map_err(|(given, width)| RowProblem::Width {
                    name: calc.name(),
                    given,
                    width,
                })
            }),
    };
    let mut out: Vec<String> = (0..header.len())
        .map(|i| fields.get(i).cloned().unwrap_or_default())
        .collect();
    match result {
        Ok(values) => {
            out.extend(values);
            out.push(String::new());
            (out, false)
        }
        Err(e) => {
            out.extend(std::iter::repeat_n(String::new(), width));
            out.push(format!("row {row_number}: {e}"));
            (out, true)
        }
    }
}

/// Guards the contract that a calculation returns one field per result column; the
/// error is (fields given, columns).
fn check_width(values: Vec<String>, width: usize) -> Result<Vec<String>, (usize, usize)> {
    if values.len() == width {
        Ok(values)
    } else {
        Err((values.len(), width))
    }
}

/// Runs a calculation over a CSV table: header and rows from `input`, the result table to
/// `output`. Returns the counts; fails only for whole-run problems (unreadable input, a
/// missing column, an output error). Rows are numbered from 1, the header not counted.
pub fn run_csv<C: Calculation + ?Sized>(
    calc: &C,
    input: impl Read,
    output: impl Write,
) -> Result<BatchSummary, BatchError<C::Error>> {
    let name = calc.name();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(input);
    let header: Vec<String> = reader
        .headers()
        .map_err(|source| BatchError::Header { name, source })?
        .iter()
        .map(str::to_string)
        .collect();
    check_header(calc, &header)?;
    let mut writer = csv::Writer::from_writer(output);
    let write_error = |source: csv::Error| BatchError::Write { name, source };
    writer
        .write_record(output_header(calc, &header))
        .map_err(write_error)?;
    let mut summary = BatchSummary {
        rows: 0,
        bad_rows: 0,
    };
    for (i, record) in reader.records().enumerate() {
        let row_number = i + 1;
        let (fields, pre_error) = match record {
            Ok(r) => {
                let fields: Vec<String> = r.iter().map(str::to_string).collect();
                let pre_error = (fields.len() != header.len()).then(|| RowProblem::FieldCount {
                    fields: fields.len(),
                    header: header.len(),
                });
                (fields, pre_error)
            }
            Err(source) if source.is_io_error() => {
                return Err(BatchError::Read {
                    name,
                    row: row_number,
                    source,
                });
            }
            Err(e) => (Vec::new(), Some(RowProblem::Unreadable(e))),
        };
        let (out, bad) = output_row(calc, &header, &fields, row_number, pre_error);
        writer.write_record(&out).map_err(write_error)?;
        summary.rows += 1;
        summary.bad_rows += usize::from(bad);
    }
    writer
        .flush()
        .map_err(|source| BatchError::Flush { name, source })?;
    Ok(summary)
}

/// The value of one command-line flag of the single-pose form, split into columns.
#[derive(Clone, Debug)]
pub struct FlagValue {
    /// The flag, e.g. `--pose`.
    pub flag: &'static str,
    /// The columns its comma-separated values fill, in order.
    pub columns: Vec<&'static str>,
    /// The text given.
    pub text: String,
}

impl FlagValue {
    /// A flag whose comma-separated values fill `columns`.
    pub fn new(flag: &'static str, columns: &[&'static str], text: &str) -> Self {
        FlagValue {
            flag,
            columns: columns.to_vec(),
            text: text.to_string(),
        }
    }

    /// The values, checked: their count and each one's syntax.
    fn values(&self) -> Result<Vec<String>, FlagValueError> {
        let values: Vec<String> = self.text.split(',').map(|v| v.trim().to_string()).collect();
        if values.len() != self.columns.len() {
            let what = if self.columns.len() == 1 {
                "one value".to_string()
            } else {
                format!("{} comma-separated numbers", self.columns.len())
            };
            return Err(FlagValueError::Count {
                flag: self.flag,
                what,
                columns: self.columns.clone(),
                given: values.len(),
            });
        }
        for (column, value) in self.columns.iter().zip(values.iter()) {
            check_field(column, value).map_err(|error| FlagValueError::Field {
                flag: self.flag,
                error,
            })?;
        }
        Ok(values)
    }
}

/// Runs a calculation on the one row the flags describe and writes the same header and
/// row the batch form would. Fails, writing nothing, if a flag or the calculation fails.
pub fn run_single<C: Calculation + ?Sized>(
    calc: &C,
    flags: &[FlagValue],
    output: impl Write,
) -> Result<(), BatchError<C::Error>> {
    let name = calc.name();
    let mut header = Vec::new();
    let mut fields = Vec::new();
    for flag in flags {
        header.extend(flag.columns.iter().map(|c| c.to_string()));
        fields.extend(flag.values()?);
    }
    let values = calc
        .compute(&Row::new(&header, &fields))
        .map_err(BatchError::Row)?;
    let values = check_width(values, calc.result_columns().len())
        .map_err(|(given, width)| BatchError::Width { name, given, width })?;
    fields.extend(values);
    fields.push(String::new());
    let mut writer = csv::Writer::from_writer(output);
    let write_error = |source: csv::Error| BatchError::Write { name, source };
    writer
        .write_record(output_header(calc, &header))
        .map_err(write_error)?;
    writer.write_record(&fields).map_err(write_error)?;
    writer
        .flush()
        .map_err(|source| BatchError::Flush { name, source })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// Why `Double` fails.
    #[derive(Debug, Error)]
    enum DoubleError {
        #[error(transparent)]
        Field(#[from] FieldError),
        #[error("double: negative")]
        Negative,
    }

    /// Doubles `a`; fails on negative values.
    struct Double;
    impl Calculation for Double {
        type Error = DoubleError;
        fn name(&self) -> &'static str {
            "double"
        }
        fn required_columns(&self) -> Vec<&'static str> {
            vec!["a"]
        }
        fn result_columns(&self) -> Vec<&'static str> {
            vec!["b"]
        }
        fn compute(&self, row: &Row<'_>) -> Result<Vec<String>, DoubleError> {
            let a = row.number("a")?;
            if a < 0.0 {
                return Err(DoubleError::Negative);
            }
            Ok(vec![format!("{}", 2.0 * a)])
        }
    }

    fn run(input: &str) -> Result<(String, BatchSummary), String> {
        let mut out = Vec::new();
        let s = run_csv(&Double, input.as_bytes(), &mut out).map_err(|e| e.to_string())?;
        Ok((String::from_utf8(out).unwrap(), s))
    }

    #[test]
    fn every_input_row_gives_one_output_row_and_bad_rows_say_why() {
        let (out, s) = run("x,a\n1,2\n2,abc\n3,-1\n4\n5,4\n").unwrap();
        assert_eq!(
            out,
            "x,a,b,error\n1,2,4,\n2,abc,,\"row 2: a: \"\"abc\"\" is not a number\"\n\
             3,-1,,row 3: double: negative\n4,,,\"row 4: has 1 fields, the header has 2\"\n5,4,8,\n"
        );
        assert_eq!(
            s,
            BatchSummary {
                rows: 5,
                bad_rows: 3
            }
        );
    }

    #[test]
    fn a_missing_column_fails_the_run_and_is_named() {
        let e = run("x,y\n1,2\n").unwrap_err();
        assert!(e.contains("\"a\""), "{e}");
        assert!(run("").unwrap_err().contains("empty"));
    }

    #[test]
    fn colliding_input_columns_are_renamed() {
        let (out, _) = run("b,a,error\n0,1,old\n").unwrap();
        assert_eq!(out, "in_b,a,in_error,b,error\n0,1,old,2,\n");
    }

    #[test]
    fn single_form_prints_the_batch_header_and_row() {
        let mut out = Vec::new();
        run_single(&Double, &[FlagValue::new("--a", &["a"], "2")], &mut out).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), "a,b,error\n2,4,\n");
        let e = run_single(&Double, &[FlagValue::new("--a", &["a"], "2,3")], Vec::new())
            .unwrap_err()
            .to_string();
        assert_eq!(e, "--a: expected one value (a), got 2");
    }
}
