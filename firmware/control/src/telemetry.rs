//! Telemetry: the status report assembled from what the tick computed (the sensing's
//! measured pose and joints, the supervisor's margins and counters, the state machine's
//! faults, the board's timing) and, as it goes out, the receiving side's link counters.
//! Nothing here evaluates a pose again.

use master_link::{LinkCounters, StatusReport, Warnings};

/// Adds the receiving side's link counters to a status about to go out, with the
/// `LINK_ERRORS` warning set while any frame has been rejected. Without counters (the
/// receiver has not counted anything yet) the link fields stay as they were.
pub fn with_link(status: &mut StatusReport, link: Option<LinkCounters>) {
    if let Some(c) = link {
        status.link = c;
        status.warnings.set(Warnings::LINK_ERRORS, c.rejected() > 0);
    }
}
