//! The one list of model families a person chooses from (`truepos fit --family`), in the
//! domain's words.
//!
//! A family fixes which terms a model may have. There are two forms, because the model the
//! control runs takes one of two forms (`truepos_model::CompensationModel`):
//! - **filtered** families ([`FilteredFamily`]): temperature rises, their low-passes and rates,
//!   operating state — a model whose filters carry history from cycle to cycle, chosen among by
//!   [`crate::train`] (baseline, rises, operating, dynamic, dynamic-rates, dynamic-running,
//!   dynamic-rates-running, transfer, transfer2, reference);
//! - **position** families ([`PositionFamily`]): the machine's temperature differences times
//!   factors of the axis positions — a function of this cycle's values, fitted by
//!   [`crate::position_model`] (prior-art, all-axes, all-axes-squared, bed-factor, own-axis,
//!   serial, reference-sensor). They need a machine file. Each builds its model through
//!   [`crate::position_model::PositionDesign`], which a caller may implement for a family of
//!   its own (docs/how-to-add-a-family.md).
//!
//! Both forms are chosen among by the same inner cross-validation and judged by the same outer
//! loop ([`crate::machine_fit`]). Names are unique across both, so one comma-separated list
//! says everything: [`Families`].
//!
//! ```
//! use truepos_fit::family::{Families, FilteredFamily, PositionFamily};
//! let f: Families = "dynamic, prior-art,bed-factor".parse().unwrap();
//! assert_eq!(f.filtered, [FilteredFamily::Dynamic]);
//! assert_eq!(f.position, [PositionFamily::PositionIndependent, PositionFamily::BedFactor]);
//! assert!("warm".parse::<Families>().unwrap_err().contains("bed-factor"));
//! ```

use std::fmt;
use std::str::FromStr;

pub use crate::features::Family as FilteredFamily;
pub use crate::position_model::Family as PositionFamily;

/// One family of either form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// A family of the filtered form.
    Filtered(FilteredFamily),
    /// A family of the position form.
    Position(PositionFamily),
}

impl Family {
    /// Every family, the filtered form first, each form simplest first.
    pub fn all() -> impl Iterator<Item = Family> {
        let filtered = FilteredFamily::ALL.into_iter().map(Family::Filtered);
        filtered.chain(PositionFamily::ALL.into_iter().map(Family::Position))
    }

    /// The name on the command line and in files.
    pub fn key(self) -> &'static str {
        match self {
            Self::Filtered(f) => f.name(),
            Self::Position(f) => f.key(),
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}

impl FromStr for Family {
    type Err = String;

    /// A [`Family::key`] (or `seed-c`, the earlier name of `reference`); the error lists every
    /// family of both forms.
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if let Some(f) = FilteredFamily::parse(s) {
            return Ok(Self::Filtered(f));
        }
        if let Ok(f) = s.parse::<PositionFamily>() {
            return Ok(Self::Position(f));
        }
        let keys: Vec<&str> = Self::all().map(Family::key).collect();
        Err(format!("expected one of {}, got `{s}`", keys.join(", ")))
    }
}

/// A comma-separated list of families, split by form: `dynamic` fixes the family,
/// `dynamic,bed-factor` lets the selection choose between two. An empty list means none.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Families {
    /// The filtered families named, in the order given.
    pub filtered: Vec<FilteredFamily>,
    /// The position families named, in the order given.
    pub position: Vec<PositionFamily>,
}

impl FromStr for Families {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let mut out = Families::default();
        for item in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match item.parse::<Family>()? {
                Family::Filtered(f) => out.filtered.push(f),
                Family::Position(f) => out.position.push(f),
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_has_one_name_and_reads_back() {
        let keys: Vec<&str> = Family::all().map(Family::key).collect();
        let mut unique = keys.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), keys.len(), "{keys:?}");
        for f in Family::all() {
            assert_eq!(f.to_string().parse::<Family>(), Ok(f));
        }
        assert_eq!(
            "seed-c".parse::<Family>(),
            Ok(Family::Filtered(FilteredFamily::Reference))
        );
    }

    #[test]
    fn a_list_splits_by_form_and_an_unknown_name_lists_them_all() {
        assert_eq!(
            "dynamic, static,".parse::<Families>(),
            Ok(Families {
                filtered: vec![FilteredFamily::Dynamic, FilteredFamily::Static],
                position: vec![]
            })
        );
        assert_eq!("".parse::<Families>(), Ok(Families::default()));
        let e = "dynamic,warm".parse::<Families>().unwrap_err();
        assert!(e.ends_with("got `warm`"), "{e}");
        for f in Family::all() {
            assert!(e.contains(f.key()), "{e}");
        }
    }
}
