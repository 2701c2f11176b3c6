//! The events the component's log must hold after the run (`--expect-event`).

use truepos_runtime::log::LoggedEvent;

/// Whether `events` hold the one `want` names: `kind`, `kind:subject` or
/// `kind:subject:text in the detail` (e.g. `sensor-fault:x_slide_bottom`,
/// `model-selected:path 1:vmc3-e2e-alternative`).
pub fn holds(events: &[LoggedEvent], want: &str) -> bool {
    let mut parts = want.splitn(3, ':');
    let kind = parts.next().unwrap_or_default();
    let subject = parts.next();
    let detail = parts.next();
    events.iter().any(|e| {
        e.kind == kind
            && subject.is_none_or(|s| e.subject == s)
            && detail.is_none_or(|d| e.detail.contains(d))
    })
}
