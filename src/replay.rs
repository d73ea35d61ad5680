//! Replays a saved recording: sends its messages, as stored, to a viewer (connect, serve or
//! spawn) through the same outlet live runs use.

use std::path::Path;
use std::time::Duration;

use crate::record::Outlet;

/// Why a replay stopped: the file is no readable recording (bad input), or the viewer did not
/// take it (a runtime failure).
#[derive(Debug, Clone, PartialEq)]
pub enum SendError {
    Recording(String),
    Viewer(String),
}

impl std::fmt::Display for SendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SendError::Recording(e) | SendError::Viewer(e) => f.write_str(e),
        }
    }
}

/// Sends every message of `path` to `outlet`; returns how many were sent.
pub fn send(path: &Path, outlet: &Outlet) -> Result<u64, SendError> {
    let mut sent = 0;
    for msg in crate::rrd::open(path).map_err(SendError::Recording)? {
        outlet.send_raw(msg.map_err(SendError::Recording)?);
        sent += 1;
    }
    outlet
        .flush(Duration::from_secs(60))
        .map_err(SendError::Viewer)?;
    Ok(sent)
}
