//! What does not change while the service runs: the machine's axes, channels and their units,
//! the envelope's limits, the names of the models, sources and sinks (`/api/info`).

use serde::Serialize;
use truepos_model::{AxisKind, OperatingKind};
use truepos_runtime::Running;

/// One axis.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct AxisInfo {
    /// Name (`X`).
    pub name: String,
    /// Unit of its offsets: `µm` (linear) or `µrad` (rotary).
    pub unit: &'static str,
    /// Unit of its position: `mm` or `deg`.
    pub position_unit: &'static str,
    /// Whether the axis is rotary.
    pub rotary: bool,
    /// The envelope: largest offset magnitude.
    pub max_offset: f64,
    /// The envelope: largest offset rate per s.
    pub max_rate_per_s: f64,
    /// Path at power-on (1-based).
    pub path: u32,
}

/// One temperature or operating channel.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ChannelInfo {
    /// Id as in the machine file.
    pub id: String,
    /// Unit (`°C` for temperatures; an operating channel's unit as the machine file states it).
    pub unit: String,
    /// Where it is (temperatures), or its kind (operating).
    pub what: String,
    /// Valid range (temperatures; `None` for operating channels).
    pub valid: Option<[f64; 2]>,
}

/// The static part of the live view.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Info {
    /// The machine's name.
    pub machine: String,
    /// Axes in machine order.
    pub axes: Vec<AxisInfo>,
    /// Temperature channels in machine order.
    pub temperatures: Vec<ChannelInfo>,
    /// Operating channels in machine order.
    pub operating: Vec<ChannelInfo>,
    /// Number of paths.
    pub paths: usize,
    /// Models of the set, in order of preference.
    pub models: Vec<String>,
    /// Sources, in service order.
    pub sources: Vec<String>,
    /// Sinks, in service order.
    pub sinks: Vec<String>,
    /// Whether the service writes a log (history and events need one).
    pub log: bool,
    /// The crate's version.
    pub version: &'static str,
}

impl Info {
    /// The static part of a started service; `source_names` in service order (the service
    /// keeps sources boxed and names them only through `source_reason`).
    pub fn of(running: &Running, source_names: Vec<String>, log: bool) -> Self {
        let s = &running.service;
        let mc = s.machine();
        let m = &mc.machine;
        let axes = m
            .axes
            .iter()
            .zip(&mc.axes)
            .map(|(a, c)| {
                let rotary = a.kind == AxisKind::Rotary;
                AxisInfo {
                    name: a.name.clone(),
                    unit: if rotary { "µrad" } else { "µm" },
                    position_unit: if rotary { "deg" } else { "mm" },
                    rotary,
                    max_offset: c.max_offset_um,
                    max_rate_per_s: c.max_rate_um_per_s,
                    path: c.path,
                }
            })
            .collect();
        let temperatures = m
            .temperatures
            .iter()
            .map(|t| ChannelInfo {
                id: t.id.clone(),
                unit: "°C".into(),
                what: t.location.clone(),
                valid: Some([t.valid_min_c, t.valid_max_c]),
            })
            .collect();
        let operating = m
            .operating
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let (what, unit) = match o.kind {
                    OperatingKind::SpindleSpeed => ("spindle speed", "1/min"),
                    OperatingKind::AxisSpeed => ("axis speed", "mm/min"),
                    OperatingKind::Torque => ("torque", "N·m"),
                    OperatingKind::Power => ("power", "W"),
                    OperatingKind::Other => ("other", ""),
                };
                let stated = mc.operating_units.get(i).filter(|u| !u.is_empty());
                ChannelInfo {
                    id: o.id.clone(),
                    unit: stated.map_or(unit.to_string(), String::clone),
                    what: what.into(),
                    valid: None,
                }
            })
            .collect();
        Self {
            machine: m.name.clone(),
            axes,
            temperatures,
            operating,
            paths: s.path_states().len(),
            models: running.model_names().to_vec(),
            sources: source_names,
            sinks: (0..s.sink_health().len())
                .map(|i| s.sink_name(i).to_string())
                .collect(),
            log,
            version: env!("CARGO_PKG_VERSION"),
        }
    }
}
