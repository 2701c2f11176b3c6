//! What every protocol's channel configuration shares: the machine channel an entry feeds,
//! named by exactly one of `temperature`, `axis` or `operating`, and its resolution against the
//! machine. The fields are declared by a macro rather than a flattened table of their own:
//! serde's `flatten` does not keep `deny_unknown_fields`' list of the keys expected, nor the
//! place in the file of a flattened value's mistake.

/// Declares a channel entry of a configuration (TOML, unknown keys refused): the protocol's own
/// fields, with `..feeds` where the three target fields stand, and `target`, their resolution.
macro_rules! channel_config {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $($(#[$before_meta:meta])* pub $before:ident: $before_ty:ty,)*
            ..feeds,
            $($(#[$after_meta:meta])* pub $after:ident: $after_ty:ty,)*
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $($(#[$before_meta])* pub $before: $before_ty,)*
            /// Machine temperature channel id (°C).
            #[serde(default)]
            pub temperature: Option<String>,
            /// Machine axis name (position in mm or degrees).
            #[serde(default)]
            pub axis: Option<String>,
            /// Machine operating channel id.
            #[serde(default)]
            pub operating: Option<String>,
            $($(#[$after_meta])* pub $after: $after_ty,)*
        }

        impl $name {
            /// The machine channel this entry feeds (exactly one of `temperature`, `axis` or
            /// `operating` must be given); `key` names the entry in errors.
            pub fn target(
                &self,
                machine: &truepos_model::Machine,
                key: &str,
            ) -> Result<truepos_runtime::sources::Target, truepos_files::InputError> {
                truepos_runtime::sources::Target::resolve(
                    machine,
                    key,
                    self.temperature.as_deref(),
                    self.axis.as_deref(),
                    self.operating.as_deref(),
                )
            }
        }
    };
}

pub(crate) use channel_config;
