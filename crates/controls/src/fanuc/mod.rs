//! FANUC: everything truepos knows of this control.
//!
//! - The linear thermal form per axis as custom macro variables ([`macro_axes`], the FOCAS
//!   `cnc_wrmacro` arguments, and a macro program: [`write_macro_program`], read back by
//!   [`read_macro_program`]), from the [`crate::projection::Form::Linear`] projection.
//! - Its pitch error compensation tapes, parameters 3620–3624 and point data ([`FanucPitch`],
//!   [`parse_fanuc`]), with what a grid loses to quantisation ([`FanucLoss`]).

mod export;
mod table;

pub use export::{macro_axes, read_macro_program, write_macro_program, FanucMacroAxis, DEC_VAL};
pub use table::{parse_fanuc, FanucAxis, FanucGrid, FanucLoss, FanucPitch};
