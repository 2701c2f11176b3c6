//! HEIDENHAIN TNC: everything truepos knows of this control.
//!
//! - Its thermal offset of PLC module 9231 ([`offset_9231`], the
//!   [`crate::projection::Form::Constant`] projection) and `TEMPCOMP` formulas over PLC words
//!   ([`tempcomp`]).
//! - Its nonlinear axis error compensation tables `*.COM` and the `*.CMA` that selects them
//!   ([`HeidenhainCom`], [`HeidenhainCma`], [`read_heidenhain`]).

mod export;
mod table;

pub use export::{offset_9231, tempcomp, ModelAt, PlcWord, Tempcomp, MODULE_9231_LIMIT};
pub use table::{parse_cma, parse_com, read_heidenhain, CmaLine, HeidenhainCma, HeidenhainCom};
