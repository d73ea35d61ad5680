//! Replays a saved recording: sends its messages, as stored, to a viewer (connect, serve or
//! spawn) through the same outlet live runs use.

use std::io::BufReader;
use std::path::Path;
use std::time::Duration;

use rerun::external::re_log_encoding::DecoderApp;

use crate::record::Outlet;

/// Sends every message of `path` to `outlet`; returns how many were sent.
pub fn send(path: &Path, outlet: &Outlet) -> Result<u64, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let decoder = DecoderApp::decode_eager(BufReader::new(file))
        .map_err(|e| format!("{}: not a Rerun recording: {e}", path.display()))?;
    let mut sent = 0;
    for msg in decoder {
        let msg = msg.map_err(|e| format!("{}: {e}", path.display()))?;
        outlet.send_raw(msg);
        sent += 1;
    }
    outlet.flush(Duration::from_secs(60))?;
    Ok(sent)
}
