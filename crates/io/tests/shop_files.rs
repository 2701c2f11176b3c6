//! Runs as shops keep them: a workbook with real date-time cells (written here by a spreadsheet
//! library, as Excel stores them: days since 1899-12-30), and the same day as a `;`-separated
//! Windows-1252 CSV with decimal commas and day-first dates. Both must read as the same run.

use std::path::{Path, PathBuf};

use rust_xlsxwriter::{ExcelDateTime, Format, Workbook};
use truepos_io::run::{read, Time};

/// A fresh directory for this test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("truepos-shop-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Ten hours at a five-minute period: (hour, minute) of each row, a spindle temperature and a
/// drift measured every other row.
fn day() -> Vec<(u8, u8, f64, Option<f64>)> {
    (0..120)
        .map(|i| {
            let minutes = 5 * i;
            let t = 21.0 + 0.05 * f64::from(i as u32);
            let drift = (i % 2 == 0).then(|| 0.4 * f64::from(i as u32));
            (6 + (minutes / 60) as u8, (minutes % 60) as u8, t, drift)
        })
        .collect()
}

fn write_workbook(path: &Path) {
    let mut book = Workbook::new();
    let sheet = book.add_worksheet();
    sheet.set_name("Montag").unwrap();
    let when = Format::new().set_num_format("dd.mm.yyyy hh:mm:ss");
    for (c, name) in ["Datum/Uhrzeit", "Spindel vorne [°C]", "Z-Drift [µm]"]
        .iter()
        .enumerate()
    {
        sheet.write_string(0, c as u16, *name).unwrap();
    }
    for (i, (h, m, t, drift)) in day().into_iter().enumerate() {
        let row = i as u32 + 1;
        let at = ExcelDateTime::from_ymd(2024, 3, 4)
            .unwrap()
            .and_hms(u16::from(h), m, 0)
            .unwrap();
        sheet
            .write_datetime_with_format(row, 0, &at, &when)
            .unwrap();
        sheet.write_number(row, 1, t).unwrap();
        if let Some(d) = drift {
            sheet.write_number(row, 2, d).unwrap();
        }
    }
    book.save(path).unwrap();
}

fn write_csv(path: &Path) {
    let mut text = String::from("Datum/Uhrzeit;Spindel vorne [°C];Z-Drift [µm]\r\n");
    for (h, m, t, drift) in day() {
        let d = drift.map_or(String::new(), |d| format!("{d}").replace('.', ","));
        let t = format!("{t}").replace('.', ",");
        text += &format!("04.03.2024 {h:02}:{m:02}:00;{t};{d}\r\n");
    }
    let (bytes, _, unmappable) = encoding_rs::WINDOWS_1252.encode(&text);
    assert!(!unmappable);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_workbook_with_date_cells_and_its_shop_csv_read_as_the_same_run() {
    let dir = scratch("dates");
    let (xlsx, csv) = (dir.join("Messung.xlsx"), dir.join("Messung.csv"));
    write_workbook(&xlsx);
    write_csv(&csv);
    let book = read(&xlsx, None).unwrap();
    let text = read(&csv, None).unwrap();
    assert_eq!(book.len(), 1);
    assert_eq!(book[0].columns, text[0].columns);
    // The date cells are date-times, not day numbers taken for seconds: five minutes apart,
    // ten hours in all — and found by their cells without naming the column.
    for time in [Time::Column("Datum/Uhrzeit".into()), Time::default()] {
        let a = book[0].times(&time).unwrap();
        let b = text[0].times(&time).unwrap();
        assert_eq!(a.len(), 120);
        assert!((a[1] - 300.0).abs() < 1e-6, "{}", a[1]);
        assert!((a[119] - 119.0 * 300.0).abs() < 1e-3, "{}", a[119]);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-3, "{x} {y}");
        }
    }
    let columns = [
        (book[0].numbers(1).unwrap(), text[0].numbers(1).unwrap()),
        (book[0].measured(2).unwrap(), text[0].measured(2).unwrap()),
    ];
    for (a, b) in columns {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert!(
                (x.is_nan() && y.is_nan()) || (x - y).abs() < 1e-9,
                "{x} {y}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
