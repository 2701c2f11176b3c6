//! Workbooks (`.xlsx`, `.xlsm`, `.xlsb`, `.xls`, `.ods`) read into the same [`Table`] as CSV,
//! through calamine (feature `xlsx`); without the feature a workbook is refused by name.

use std::path::Path;

#[cfg(feature = "xlsx")]
use calamine::{open_workbook_auto_from_rs, Data, Reader};

use super::Table;
#[cfg(feature = "xlsx")]
use super::Value;
use truepos_files::InputError;

/// Reads a workbook (`.xlsx`, `.xlsm`, `.xlsb`, `.xls`, `.ods` through calamine): every
/// non-empty sheet (or only `sheet`) is one table; the first non-empty row of a sheet holds the
/// column names. A sheet without data rows is skipped, or an error when it was asked for by
/// name; a workbook with none is an error.
#[cfg(feature = "xlsx")]
pub fn read_workbook(file: &Path, sheet: Option<&str>) -> Result<Vec<Table>, InputError> {
    let bytes = truepos_files::read::read(file, truepos_files::RUN)?;
    let mut wb = open_workbook_auto_from_rs(std::io::Cursor::new(bytes))
        .map_err(|e| InputError::file(file, format!("cannot open the workbook: {e}")))?;
    let names = wb.sheet_names();
    let wanted: Vec<String> = match sheet {
        Some(s) if names.iter().any(|n| n == s) => vec![s.to_string()],
        Some(s) => {
            return Err(InputError::file(
                file,
                format!("no sheet `{s}`; the sheets are: {}", names.join(", ")),
            ))
        }
        None => names.clone(),
    };
    let mut out = Vec::new();
    for name in wanted {
        let range = wb
            .worksheet_range(&name)
            .map_err(|e| InputError::file(file, format!("sheet `{name}`: cannot read it: {e}")))?;
        let Some((r0, c0)) = range.start() else {
            if sheet.is_some() {
                return Err(InputError::file(file, format!("sheet `{name}` is empty")));
            }
            continue;
        };
        let mut rows = range.rows();
        let header = rows.next().unwrap_or(&[]);
        let (header_line, first_column) = (r0 as usize + 1, c0 as usize + 1);
        let mut columns = Vec::with_capacity(header.len());
        for (c, cell) in header.iter().enumerate() {
            match cell {
                Data::String(s) if !s.trim().is_empty() => columns.push(s.trim().to_string()),
                other => {
                    return Err(InputError::at(
                        file,
                        header_line,
                        first_column + c,
                        format!("sheet `{name}`"),
                        format!("expected a column name in the header row, got {other:?}"),
                    ))
                }
            }
        }
        let mut table = Table {
            first_column,
            ..Table::new(file, Some(name.clone()), columns, header_line)
        };
        for (i, row) in rows.enumerate() {
            let line = header_line + 1 + i;
            table.start_row(line);
            for c in 0..table.columns.len() {
                let text;
                let value = match row.get(c) {
                    Some(Data::Float(v)) if v.is_finite() => Value::Number(*v),
                    Some(Data::Int(v)) => Value::Number(*v as f64),
                    Some(Data::Empty) | None => Value::Empty,
                    Some(Data::String(s)) => Value::Text(s.as_str()),
                    Some(Data::DateTime(d)) => {
                        text = workbook_date_time(d);
                        Value::Text(&text)
                    }
                    Some(other) => {
                        text = other.to_string();
                        Value::Text(&text)
                    }
                };
                table.push_cell(
                    value,
                    u32::try_from(line).unwrap_or(u32::MAX),
                    u32::try_from(first_column + c).unwrap_or(u32::MAX),
                );
            }
        }
        if table.is_empty() {
            if sheet.is_some() {
                return Err(InputError::file(
                    file,
                    format!("sheet `{name}` has a header row but no data rows"),
                ));
            }
            continue;
        }
        out.push(table);
    }
    if out.is_empty() {
        return Err(InputError::file(
            file,
            "every sheet of the workbook is empty",
        ));
    }
    Ok(out)
}

/// A workbook's date-time cell as the ISO 8601 text a time column reads
/// ([`crate::timestamp::parse`]), to the millisecond the workbook keeps: the cell holds days
/// since the workbook's epoch, and read as a number it would pass for seconds. A duration cell
/// (`[h]:mm:ss`) is its length in seconds.
#[cfg(feature = "xlsx")]
fn workbook_date_time(cell: &calamine::ExcelDateTime) -> String {
    if cell.is_duration() {
        return format!("{}", cell.as_f64() * 86_400.0);
    }
    let (y, mo, d, h, mi, s, ms) = cell.to_ymd_hms_milli();
    format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{ms:03}")
}

/// Without the `xlsx` feature there is no workbook reader: a workbook is refused by name rather
/// than read as CSV text.
#[cfg(not(feature = "xlsx"))]
pub fn read_workbook(file: &Path, _sheet: Option<&str>) -> Result<Vec<Table>, InputError> {
    Err(InputError::file(file, NO_XLSX))
}

/// Why a build without the `xlsx` feature refuses a workbook, and what to do instead.
#[cfg(not(feature = "xlsx"))]
const NO_XLSX: &str = "this build reads no XLSX; it was built without truepos-io's `xlsx` \
     feature (the LinuxCNC component reads CSV only): save the sheet as CSV, or read the \
     workbook with `truepos`";

/// Whether `file` names a workbook by its extension.
pub fn is_workbook(file: &Path) -> bool {
    let ext = file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(
        ext.as_deref(),
        Some("xlsx" | "xlsm" | "xlsb" | "xls" | "ods")
    )
}
