//! Damaged inputs at the command line's boundary: recordings (`export`, `replay --resimulate`,
//! `replay`), checkpoints (`resume`) and scripts (`record --script`) with bit flips,
//! truncations, splices and random bytes end with exit code 0 (what is left is usable), 2 (a
//! message naming the file) or 3 (an unstable run) — never a panic, an abort, a hang, or
//! gigabytes allocated from a damaged length field.
//!
//! Besides the seeded random damage, fixed cases damage one length field of a real recording
//! each, where the Rerun SDK's decoder used to panic or allocate what the field claims: the
//! framing's message length, an Arrow message's uncompressed size, an Arrow IPC metadata
//! length, and an Arrow buffer's length (the Arrow reader panicked slicing it).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use re_protos::log_msg::v1alpha1::ArrowMsg;
use rerun::external::arrow::ipc::root_as_message;
use rerun::external::re_log_encoding::external::lz4_flex;
use rerun::external::re_log_encoding::{Decodable, Encodable};

fn temp(name: &str) -> PathBuf {
    crate::common::temp("damaged_inputs", name)
}

/// A run that takes longer than this hangs (or allocates and fills gigabytes: the 2 GB
/// metadata length took 35 s).
const LIMIT: Duration = Duration::from_secs(20);

/// xorshift64: the damage is the same on every run.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 % n.max(1) as u64) as usize
    }

    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.below(256) as u8).collect()
    }
}

/// How a run ended: its exit code (None if killed at `LIMIT`, which only `serving` allows) and
/// its stderr.
fn run(args: &[&str], serving: bool) -> (Option<i32>, String) {
    static RUNS: AtomicUsize = AtomicUsize::new(0);
    let err = temp(&format!("stderr-{}", RUNS.fetch_add(1, Ordering::Relaxed)));
    let mut child = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > LIMIT {
            child.kill().unwrap();
            child.wait().unwrap();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = std::fs::read_to_string(&err).unwrap_or_default();
    let Some(status) = status else {
        // A served replay keeps serving until Ctrl-C: the file was accepted.
        assert!(serving, "{args:?} ran over {LIMIT:?}: {stderr}");
        return (None, stderr);
    };
    // A panic exits with 101; an abort (a failed allocation) ends with a signal.
    let code = status.code();
    assert!(code.is_some(), "{args:?}: ended by {status}: {stderr}");
    (code, stderr)
}

/// Runs `args` on the damaged `file`: exit 0, 2 with a message naming the file, or 3 with the
/// reason the run became unstable (damaged values can make it so). Returns the exit code and
/// stderr.
fn boundary(file: &Path, args: &[&str]) -> (Option<i32>, String) {
    let (code, stderr) = run(args, args.contains(&"--serve"));
    let what = format!("{args:?} on {}", file.display());
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    assert!(
        code.is_none() || matches!(code, Some(0 | 2 | 3)),
        "{what}: exit {code:?} (a panic is 101): {stderr}"
    );
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("error: "))
        .collect();
    if code == Some(2) {
        let named = errors
            .iter()
            .any(|l| l.contains(&file.display().to_string()));
        assert!(
            named,
            "{what}: exit 2, no message naming the file: {stderr}"
        );
    }
    if code == Some(3) {
        assert!(
            !errors.is_empty(),
            "{what}: exit 3 without its reason: {stderr}"
        );
    }
    (code, stderr)
}

/// The recording's readers: export and re-simulation (serving, with `serve`, too).
fn read_recording(file: &Path, serve: bool) -> Vec<(Option<i32>, String)> {
    let f = file.to_str().unwrap();
    let out = temp("resim.rrd");
    let dir = temp("export");
    let mut codes = vec![
        boundary(file, &["export", f, "-o", dir.to_str().unwrap()]),
        boundary(
            file,
            &[
                "replay",
                "--resimulate",
                f,
                "-o",
                out.to_str().unwrap(),
                "-q",
            ],
        ),
    ];
    if serve {
        codes.push(boundary(file, &["replay", f, "--serve", "127.0.0.1:0"]));
    }
    codes
}

/// Seeded damage of `good` (and `other` for splices): `count` single bit flips, and a quarter
/// as many each of truncations, splices and random bytes (half of them behind `good`'s first
/// 32 bytes, so that the magic and the first lengths read as valid).
fn damaged(good: &[u8], other: &[u8], rng: &mut Rng, count: usize) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for i in 0..count {
        let mut b = good.to_vec();
        let at = rng.below(b.len());
        b[at] ^= 1 << rng.below(8);
        out.push((format!("flip{i}"), b));
    }
    for i in 0..count / 4 {
        out.push((format!("cut{i}"), good[..rng.below(good.len())].to_vec()));
        let mut b = good[..rng.below(good.len())].to_vec();
        b.extend(&other[rng.below(other.len())..]);
        out.push((format!("splice{i}"), b));
        let mut b = if i % 2 == 0 {
            good[..32.min(good.len())].to_vec()
        } else {
            Vec::new()
        };
        let n = rng.below(4096);
        b.extend(rng.bytes(n));
        out.push((format!("random{i}"), b));
    }
    out.push(("empty".into(), Vec::new()));
    out
}

/// Writes each variant next to the others as `stem-NAME.ext` and returns the paths.
fn write_all(variants: Vec<(String, Vec<u8>)>, stem: &str, ext: &str) -> Vec<PathBuf> {
    variants
        .into_iter()
        .map(|(name, bytes)| {
            let path = temp(&format!("{stem}-{name}.{ext}"));
            std::fs::write(&path, bytes).unwrap();
            path
        })
        .collect()
}

/// A directory and a missing file in place of a file.
fn not_files(stem: &str) -> Vec<PathBuf> {
    let dir = temp(&format!("{stem}-a-directory"));
    std::fs::create_dir_all(&dir).unwrap();
    vec![dir, temp(&format!("{stem}-missing"))]
}

/// One small scripted recording, with a checkpoint at step 20 of 30: the originals to damage.
fn originals() -> (Vec<u8>, Vec<u8>, String) {
    let script = "# a comment\nat 5 steps set chi 0.9\nat 10 steps set every 5\n\
                  at 25 steps set m 3 restart\n";
    let path = temp("script.txt");
    std::fs::write(&path, script).unwrap();
    let rrd = temp("good.rrd");
    let out = crate::common::peridyn(&[
        "record",
        "abc-wave-1d",
        "--variant",
        "small",
        "--steps",
        "30",
        "--checkpoint-every",
        "20",
        "--script",
        path.to_str().unwrap(),
        "-o",
        rrd.to_str().unwrap(),
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rrd_bytes = std::fs::read(&rrd).unwrap();
    let ckpt = std::fs::read(rrd.with_extension("ckpt")).unwrap();
    (rrd_bytes, ckpt, script.into())
}

/// The recording's frames after its stream header: (offset of the message header, kind,
/// payload length).
fn frames(rrd: &[u8]) -> Vec<(usize, u64, usize)> {
    let word = |at: usize| u64::from_le_bytes(rrd[at..at + 8].try_into().unwrap());
    let mut out = Vec::new();
    let mut at = 12;
    while at + 16 <= rrd.len() {
        let (kind, len) = (word(at), word(at + 8) as usize);
        out.push((at, kind, len));
        if kind == 0 {
            break;
        }
        at += 16 + len;
    }
    out
}

/// The recording with its Arrow message (kind 2) number `index` replaced by `damage` of it.
fn with_arrow(rrd: &[u8], index: usize, damage: impl FnOnce(&mut ArrowMsg)) -> Vec<u8> {
    let arrows: Vec<_> = frames(rrd).into_iter().filter(|f| f.1 == 2).collect();
    let (at, _, len) = arrows[index % arrows.len()];
    let mut msg = ArrowMsg::from_rrd_bytes(&rrd[at + 16..at + 16 + len]).unwrap();
    damage(&mut msg);
    let mut payload = Vec::new();
    msg.to_rrd_bytes(&mut payload).unwrap();
    let mut out = rrd[..at + 8].to_vec();
    out.extend((payload.len() as u64).to_le_bytes());
    out.extend(payload);
    out.extend(&rrd[at + 16 + len..]);
    out
}

/// An Arrow message's IPC stream, changed by `damage` and compressed again.
fn with_ipc(msg: &mut ArrowMsg, damage: impl FnOnce(&mut Vec<u8>)) {
    let mut ipc =
        lz4_flex::block::decompress(&msg.payload, msg.uncompressed_size as usize).unwrap();
    damage(&mut ipc);
    msg.uncompressed_size = ipc.len() as u64;
    msg.payload = lz4_flex::block::compress(&ipc).into();
}

/// The first Arrow IPC message of a stream (the schema) and where the second begins.
fn ipc_message(ipc: &[u8], at: usize) -> (usize, usize, usize) {
    let meta_len = i32::from_le_bytes(ipc[at + 4..at + 8].try_into().unwrap()) as usize;
    let meta = at + 8;
    let body = root_as_message(&ipc[meta..meta + meta_len])
        .unwrap()
        .bodyLength() as usize;
    (meta, meta_len, meta + meta_len + body)
}

/// Each damaged length field of the fixed cases, and what the refusal says.
fn fixed_cases(rrd: &[u8]) -> Vec<(&'static str, Vec<u8>, &'static str)> {
    // The framing: the second message claims 2⁶² bytes. What comes before it is read (as for
    // a file cut short), so this one may also end in 0.
    let mut framing = rrd.to_vec();
    let (at, _, _) = frames(rrd)[1];
    framing[at + 8..at + 16].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let uncompressed = with_arrow(rrd, 0, |m| m.uncompressed_size = 1 << 40);
    let metadata = with_arrow(rrd, 0, |m| {
        with_ipc(m, |ipc| ipc[4..8].copy_from_slice(&i32::MAX.to_le_bytes()))
    });
    // The record batch's first non-empty buffer claims an absurd length (the bytes of the
    // damaged file the decoder panicked on: `slice offset=320 length=11671340221177266192`).
    let buffer = with_arrow(rrd, 0, |m| {
        with_ipc(m, |ipc| {
            let (_, _, batch) = ipc_message(ipc, 0);
            let (meta, meta_len, _) = ipc_message(ipc, batch);
            let message = root_as_message(&ipc[meta..meta + meta_len]).unwrap();
            let b = message
                .header_as_record_batch()
                .unwrap()
                .buffers()
                .unwrap()
                .iter()
                .find(|b| b.length() > 0)
                .unwrap();
            let mut pattern = b.offset().to_le_bytes().to_vec();
            pattern.extend(b.length().to_le_bytes());
            let k = ipc[meta..meta + meta_len]
                .windows(16)
                .position(|w| w == pattern)
                .unwrap();
            let huge: u64 = 11_671_340_221_177_266_192;
            ipc[meta + k + 8..meta + k + 16].copy_from_slice(&huge.to_le_bytes());
        })
    });
    vec![
        ("framing", framing, ""),
        (
            "uncompressed",
            uncompressed,
            "claims 1099511627776 bytes uncompressed",
        ),
        ("metadata", metadata, "claims 2147483647 bytes of metadata"),
        (
            "buffer",
            buffer,
            "not a valid Rerun recording (the offset of the new Buffer",
        ),
    ]
}

#[test]
fn damaged_recordings_checkpoints_and_scripts_are_refused_naming_the_file() {
    let started = Instant::now();
    let (rrd, ckpt, script) = originals();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut runs = 0;

    // The fixed cases: each refused (exit 2) by every reader, the framing's cut included
    // when nothing is left before it.
    for (name, bytes, needle) in fixed_cases(&rrd) {
        let path = temp(&format!("fixed-{name}.rrd"));
        std::fs::write(&path, bytes).unwrap();
        let codes = read_recording(&path, !needle.is_empty());
        runs += codes.len();
        if !needle.is_empty() {
            for (code, stderr) in codes {
                assert_eq!(code, Some(2), "{name}: {stderr}");
                assert!(stderr.contains(needle), "{name}: {stderr}");
            }
        }
    }

    // Recordings; splices join a prefix to a suffix from anywhere in the file.
    let mut spliced = rrd.clone();
    spliced.rotate_left(rrd.len() / 3);
    let mut variants = damaged(&rrd, &spliced, &mut rng, 24);
    // Most flips of compressed bytes fail LZ4's own checks: these reach the Arrow reader.
    for i in 0..24 {
        let (index, byte, bit) = (rng.below(64), rng.below(1 << 16), rng.below(8));
        let b = with_arrow(&rrd, index, |m| {
            with_ipc(m, |ipc| {
                let at = byte % ipc.len();
                ipc[at] ^= 1 << bit;
            })
        });
        variants.push((format!("ipc{i}"), b));
    }
    let mut accepted = 0;
    for path in write_all(variants, "rrd", "rrd")
        .into_iter()
        .chain(not_files("rrd"))
    {
        let codes = read_recording(&path, false);
        accepted += codes.iter().filter(|(c, _)| *c == Some(0)).count();
        runs += codes.len();
    }
    assert!(
        accepted > 0,
        "some single bit flips leave a usable recording"
    );

    // Checkpoints: damaged bytes fail the checksum or the length; damage behind a checksum
    // computed again reaches the header's and the state's decoders.
    let mut variants = damaged(&ckpt, &rrd, &mut rng, 8);

    for i in 0..16 {
        let mut b = ckpt.clone();
        let at = 31 + rng.below(b.len() - 39);
        b[at] ^= 1 << rng.below(8);
        variants.push((format!("sealed{i}"), seal(b)));
    }
    for path in write_all(variants, "ckpt", "ckpt")
        .into_iter()
        .chain(not_files("ckpt"))
    {
        let out = temp("resumed.rrd");
        boundary(
            &path,
            &[
                "resume",
                path.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "-q",
            ],
        );
        runs += 1;
    }

    // A cadence out of range used to reach the command line's `--checkpoint-every` check,
    // which did not name the file.
    let pattern = b"checkpoint_every = \"20 steps\"";
    let at = ckpt
        .windows(pattern.len())
        .position(|w| w == pattern)
        .unwrap()
        + 20;
    let mut zero = ckpt.clone();
    zero[at..at + 2].copy_from_slice(b"00");
    let path = temp("ckpt-cadence.ckpt");
    std::fs::write(&path, seal(zero)).unwrap();
    let out = temp("resumed.rrd");
    let (code, stderr) = boundary(
        &path,
        &[
            "resume",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("checkpoint_every: `00 steps`: the cadence must be > 0"),
        "{stderr}"
    );
    runs += 1;

    // Scripts.
    for path in write_all(
        damaged(script.as_bytes(), &rrd, &mut rng, 16),
        "script",
        "txt",
    )
    .into_iter()
    .chain(not_files("script"))
    {
        let out = temp("scripted.rrd");
        let args = [
            "record",
            "abc-wave-1d",
            "--variant",
            "small",
            "--steps",
            "30",
            "-q",
            "--script",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        boundary(&path, &args);
        runs += 1;
    }
    eprintln!("{runs} runs in {:.1} s", started.elapsed().as_secs_f64());
}

/// A checkpoint's bytes with its checksum (FNV-1a over everything before it) made to match.
fn seal(mut bytes: Vec<u8>) -> Vec<u8> {
    let end = bytes.len() - 8;
    let sum = bytes[..end].iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    bytes[end..].copy_from_slice(&sum.to_le_bytes());
    bytes
}
