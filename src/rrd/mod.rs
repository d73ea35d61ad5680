//! Opens a `.rrd` file for decoding with the Rerun SDK, so that a damaged file is an error
//! naming it and never a crash: every reader of recordings (`readback`, `replay`) goes through
//! [`open`].
//!
//! The SDK decodes in two layers, and damage takes the process down in both:
//! - the framing and the Protobuf messages (`DecoderTransport`): a damaged message length is
//!   allocated before it is read (a flipped high bit asks for exabytes; the failed allocation
//!   aborts). [`bounds::decodable_prefix`] gives the decoder only the bytes before the first
//!   message that would run past the end of the file;
//! - the Arrow payloads (`ToApplication`): a damaged uncompressed size or Arrow IPC length is
//!   allocated (and zero-filled) before it is read, and damaged Arrow metadata makes the Arrow
//!   reader panic (a buffer slice out of range). [`bounds::unpack_arrow`] checks those lengths
//!   first, and each decoding step runs under `catch_unwind`: a panic becomes an error.

mod bounds;

use std::cell::Cell;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom, Take};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Once;

use re_protos::log_msg::v1alpha1::log_msg::Msg;
use rerun::external::re_log_encoding::{
    CachingApplicationIdInjector, CodecError, DecoderIterator, DecoderTransport, ToApplication,
};
use rerun::log::LogMsg;

/// The messages of a recording file, in order; the first error ends them.
pub struct Messages {
    decoder: Option<DecoderIterator<Msg, BufReader<Take<File>>>>,
    /// Recovers the application id of messages written without one (older SDKs), as the SDK's
    /// own decoder does.
    app_ids: CachingApplicationIdInjector,
    path: PathBuf,
}

/// Opens `path` and reads its first message (a file that is no recording at all is refused
/// here).
pub fn open(path: &Path) -> Result<Messages, String> {
    let named = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut file = File::open(path).map_err(named)?;
    let size = file.metadata().map_err(named)?.len();
    let prefix = bounds::decodable_prefix(&mut file, size).map_err(named)?;
    file.seek(SeekFrom::Start(0)).map_err(named)?;
    let reader = BufReader::new(file.take(prefix));
    let decoder = guarded(path, || DecoderTransport::decode_eager(reader))?
        .map_err(|e| format!("{}: not a Rerun recording: {e}", path.display()))?;
    Ok(Messages {
        decoder: Some(decoder),
        app_ids: CachingApplicationIdInjector::default(),
        path: path.to_path_buf(),
    })
}

impl Messages {
    /// The next message, None at the end of the file.
    fn decode_next(&mut self) -> Result<Option<LogMsg>, String> {
        let named = |e: &dyn std::fmt::Display| format!("{}: {e}", self.path.display());
        let Some(decoder) = self.decoder.as_mut() else {
            return Ok(None);
        };
        loop {
            let Some(msg) = guarded(&self.path, || decoder.next())? else {
                return Ok(None);
            };
            let mut msg = msg.map_err(|e| named(&e))?;
            if let Msg::ArrowMsg(arrow) = &mut msg {
                bounds::unpack_arrow(arrow).map_err(|e| named(&e))?;
            }
            let app_ids = &mut self.app_ids;
            match guarded(&self.path, || msg.to_application((app_ids, None)))? {
                Ok(msg) => return Ok(Some(msg)),
                // The SDK's decoder drops these too: nothing names where they belong.
                Err(CodecError::StoreIdMissingApplicationId { .. }) => continue,
                Err(e) => return Err(named(&e)),
            }
        }
    }
}

impl Iterator for Messages {
    type Item = Result<LogMsg, String>;

    fn next(&mut self) -> Option<Self::Item> {
        let next = self.decode_next().transpose();
        if !matches!(next, Some(Ok(_))) {
            // After an error the decoder's state is not to be trusted (after a panic, not even
            // its invariants): nothing more is read.
            self.decoder = None;
        }
        next
    }
}

thread_local! {
    /// Whether a panic on this thread is one [`guarded`] turns into an error (and so is not
    /// printed).
    static DECODING: Cell<bool> = const { Cell::new(false) };
}

/// Runs one decoding step of `path`; a panic inside it becomes an error naming the file. The
/// panic hook stays quiet for this thread during the step only: every other panic (other
/// threads, our own code) goes to the hook that was installed before.
fn guarded<T>(path: &Path, step: impl FnOnce() -> T) -> Result<T, String> {
    static QUIET_HOOK: Once = Once::new();
    QUIET_HOOK.call_once(quiet_while_decoding);
    let was = DECODING.with(|d| d.replace(true));
    let outcome = catch_unwind(AssertUnwindSafe(step));
    DECODING.with(|d| d.set(was));
    outcome.map_err(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "the decoder failed".into());
        format!("{}: not a valid Rerun recording ({why})", path.display())
    })
}

/// Wraps the panic hook in force: it sees every panic but those of a decoding step.
fn quiet_while_decoding() {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !DECODING.with(Cell::get) {
            previous(info);
        }
    }));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Panics whose message holds `marker` that reached the hook in force before ours.
    static SEEN: AtomicUsize = AtomicUsize::new(0);

    #[test]
    fn a_decoding_panic_is_an_error_and_other_panics_still_reach_the_previous_hook() {
        let marker = "rrd-hook-test";
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if info.to_string().contains(marker) {
                SEEN.fetch_add(1, Ordering::SeqCst);
            }
            default(info);
        }));
        // Over the counting hook (`guarded` wraps the hook only once per process, and another
        // test may have made it wrap the default one already).
        quiet_while_decoding();
        let e = guarded(Path::new("x.rrd"), || -> u8 { panic!("{marker}: slice") });
        assert_eq!(
            e.unwrap_err(),
            format!("x.rrd: not a valid Rerun recording ({marker}: slice)")
        );
        assert_eq!(
            SEEN.load(Ordering::SeqCst),
            0,
            "a decoding panic is not printed"
        );
        assert_eq!(guarded(Path::new("x.rrd"), || 7), Ok(7));
        // Outside a decoding step, on this thread and on another, the previous hook sees it.
        assert!(std::panic::catch_unwind(|| panic!("{marker}: ours")).is_err());
        let other = std::thread::spawn(move || panic!("{marker}: other thread"));
        assert!(other.join().is_err());
        assert_eq!(SEEN.load(Ordering::SeqCst), 2);
    }
}
