//! ISG kernel (Beckhoff TwinCAT CNC): everything truepos knows of this control.
//!
//! - Its temperature compensation as axis parameter list entries P-AXIS-00271…00274
//!   ([`write_parameters`], read back by [`read_parameters`]), from the
//!   [`crate::projection::Form::Linear`] projection.
//! - Its leadscrew error compensation lists `kw.ssfk.*` ([`IsgSsfk`], [`parse_isg`]).

mod export;
mod table;

pub use export::{read_parameters, write_parameters, IsgTempComp};
pub use table::{parse_isg, IsgSsfk};
