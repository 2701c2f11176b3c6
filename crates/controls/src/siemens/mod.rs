//! Siemens SINUMERIK 840D sl / 828D: everything truepos knows of this control.
//!
//! - Its temperature compensation, set from a projected model by a part program of setting data
//!   SD43900/43910/43920 ([`write_program`], read back by [`read_program`]).
//! - Its compensation tables, INI part programs of `$AA_ENC_COMP` and `$AN_CEC`
//!   ([`SiemensTable`], [`parse_siemens`], [`write_siemens`], [`select_siemens`]).
//!
//! Its projection is [`crate::projection::Form::Linear`]; the OPC UA sink writes the same three
//! setting data to the control's nodes (docs/controls.md).

mod export;
mod table;

pub use export::{read_program, write_program, AxisSetting};
pub use table::{parse_siemens, select_siemens, write_siemens, SiemensKind, SiemensTable};
