//! `truepos update-period`: how stale a position-dependent term gets between updates while its
//! axis moves (the timing argument, `truepos_model::update_period`).

use crate::error::CliError;
use truepos_io::limits::finite_in;
use truepos_model::{travel_per_update_mm, update_error_fraction, PositionFactor};

/// Arguments of `truepos update-period`.
#[derive(clap::Args)]
pub struct Args {
    /// Maximum feed of the axis in m/min, 0.001–1000.
    #[arg(long, default_value_t = 100.0, value_parser = finite_in(0.001, 1000.0))]
    feed_m_min: f64,
    /// Update period of the position-dependent terms in ms, 0.001–60 000.
    #[arg(long, default_value_t = 4.0, value_parser = finite_in(0.001, 60_000.0))]
    period_ms: f64,
    /// Length of the axis (travel) in mm, 0.001–100 000.
    #[arg(long, default_value_t = 500.0, value_parser = finite_in(0.001, 100_000.0))]
    length_mm: f64,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> Result<(), CliError> {
    let feed_mm_min = args.feed_m_min * 1000.0;
    let travel = travel_per_update_mm(feed_mm_min, args.period_ms);
    let pct = |f| 100.0 * update_error_fraction(feed_mm_min, args.period_ms, args.length_mm, f);
    let (ratio, square, bed) = (
        pct(PositionFactor::Ratio),
        pct(PositionFactor::RatioSquared),
        pct(PositionFactor::BedFactor),
    );
    if args.json {
        let v = serde_json::json!({
            "feed_m_min": args.feed_m_min,
            "period_ms": args.period_ms,
            "length_mm": args.length_mm,
            "travel_per_update_mm": travel,
            "worst_error_percent": { "ratio": ratio, "ratio_squared": square, "bed": bed },
        });
        println!("{v}");
    } else {
        println!(
            "at {} m/min the axis travels {travel:.2} mm in {} ms; on {} mm of travel a position-dependent term is off by at most:",
            args.feed_m_min, args.period_ms, args.length_mm
        );
        println!("  ratio r        {ratio:.1} %");
        println!("  ratio squared  {square:.1} %");
        println!("  bed factor     {bed:.1} %");
    }
    Ok(())
}
