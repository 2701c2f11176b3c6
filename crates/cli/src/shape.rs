//! The shapes run files come in, as `truepos fit`, `eval` and `report` take them: the CSV
//! separator, a column that splits a file into runs, and runs without a time column.

use truepos_io::run::{Shape, Time};
use truepos_io::table::Delimiter;

/// Options on how run files are laid out (flattened into each command's arguments).
#[derive(clap::Args, Clone, Debug)]
pub struct ShapeArgs {
    /// Field separator of CSV runs: auto (the most frequent of `,`, `;` and tab outside quotes
    /// in the header line), `,`, `;` or tab. With `;` or tab, numbers may have a decimal comma
    /// (`20,5`).
    #[arg(long, default_value = "auto")]
    delimiter: Delimiter,
    /// A column naming the run of each row: a file holding several runs is split into one run
    /// per value (in order of first appearance; the rows of a run must be together), and each
    /// run is named by its value in the output.
    #[arg(long)]
    run_column: Option<String>,
    /// Seconds between rows, for runs without a time column: row i is at i × period,
    /// 10⁻⁶–10⁶ s.
    #[arg(long, value_parser = truepos_io::limits::finite_in(1e-6, 1e6))]
    sample_period: Option<f64>,
    /// How the time column's date-times are written, `strftime`-style, when neither ISO 8601
    /// nor day-first `dd.mm.yyyy HH:MM[:SS]`: e.g. `%m/%d/%Y %I:%M %p` for `03/01/2024 08:00 PM`
    /// (`%z` for an offset; else taken as written).
    #[arg(long)]
    time_format: Option<String>,
}

impl ShapeArgs {
    /// The file layout for io's readers.
    pub fn shape(&self) -> Shape {
        Shape {
            delimiter: self.delimiter,
            run_column: self.run_column.clone(),
            time_format: self.time_format.clone(),
        }
    }

    /// The time of a run: the sample period if given, else `column`.
    pub fn time(&self, column: Option<&str>) -> Option<Time> {
        match (self.sample_period, column) {
            (Some(p), _) => Some(Time::Period(p)),
            (None, Some(c)) => Some(Time::Column(c.to_string())),
            (None, None) => None,
        }
    }
}
