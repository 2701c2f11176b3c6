//! The service's configuration — the machine as the service runs it and the models with their
//! axis combinations — is the core's ([`truepos_model::config`]), so that the file formats and
//! the service share it; named here for the service's users.

pub use truepos_model::config::*;
