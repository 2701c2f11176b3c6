//! # truepos-io — the file formats of truepos
//!
//! Machine descriptions ([`machine_file`]), model files of either form ([`model_file`]) and
//! recorded cycles ([`cycles`]). Every parser returns an [`truepos_files::InputError`] that names the file, the
//! line and column, the key and what was expected; none panics on bad input.
//!
//! ```
//! use std::path::Path;
//! let text = r#"
//! [machine]
//! name = "lathe"
//! [[axis]]
//! name = "X"
//! kind = "linear"
//! travel = [0.0, -5.0]
//! "#;
//! let err = truepos_io::machine_file::parse(Path::new("lathe.toml"), text).unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "lathe.toml:7:10: `axis[0].travel`: expected [min, max] with max > min (travel > 0), got [0, -5]"
//! );
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cycles;
pub mod error;
pub mod kinematics_file;
pub mod limits;
pub mod machine_file;
pub mod model_file;
pub mod run;
pub mod table;
pub mod timestamp;
pub mod units;
