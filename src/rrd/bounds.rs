//! The length fields of a recording, checked against the bytes that hold them before anything
//! is allocated from them: the SDK's decoder and the Arrow reader allocate what a length field
//! says first and read afterwards, so one flipped bit asks for gigabytes (or exabytes, and the
//! failed allocation aborts the process).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

use re_protos::common::v1alpha1::Compression;
use re_protos::log_msg::v1alpha1::ArrowMsg;
use rerun::external::arrow::ipc::{MessageHeader as IpcHeader, root_as_message};
use rerun::external::re_log_encoding::external::lz4_flex;
use rerun::external::re_log_encoding::{
    Decodable, MessageHeader, MessageKind, StreamFooter, StreamHeader,
};

/// LZ4 expands a compressed byte to at most 255 bytes (a match length continues in steps of
/// 255 per byte).
const LZ4_MAX_RATIO: u64 = 255;

/// How many leading bytes of the file the decoder may see: all of them, or up to the header of
/// the first message whose stated length runs past the end of the file — what the decoder
/// yields for a file cut short anyway. Walks the framing as the decoder does (seeking over
/// payloads); where the decoder would stop or refuse (a bad stream header or footer) the walk
/// goes on as if it had not, which can only cut later.
pub fn decodable_prefix(file: &mut File, size: u64) -> std::io::Result<u64> {
    enum Expect {
        StreamHeader,
        MessageHeader,
        StreamFooter,
    }
    const STREAM_HEADER: u64 = StreamHeader::ENCODED_SIZE_BYTES as u64;
    const MESSAGE_HEADER: u64 = MessageHeader::ENCODED_SIZE_BYTES as u64;
    const STREAM_FOOTER: u64 = StreamFooter::ENCODED_SIZE_BYTES as u64;
    let mut expect = Expect::StreamHeader;
    let mut pos = 0u64;
    loop {
        let left = size - pos;
        match expect {
            Expect::StreamHeader if left >= STREAM_HEADER => {
                pos += STREAM_HEADER;
                expect = Expect::MessageHeader;
            }
            Expect::MessageHeader if left >= MESSAGE_HEADER => {
                let mut bytes = [0u8; MessageHeader::ENCODED_SIZE_BYTES];
                file.seek(SeekFrom::Start(pos))?;
                file.read_exact(&mut bytes)?;
                let Ok(header) = MessageHeader::from_rrd_bytes(&bytes) else {
                    // The decoder takes an unknown kind for the start of a concatenated stream.
                    expect = Expect::StreamHeader;
                    continue;
                };
                if header.len > left - MESSAGE_HEADER {
                    return Ok(pos);
                }
                pos += MESSAGE_HEADER + header.len;
                if header.kind == MessageKind::End {
                    expect = Expect::StreamFooter;
                }
            }
            Expect::StreamFooter if left >= STREAM_FOOTER => {
                pos += STREAM_FOOTER;
                expect = Expect::StreamHeader;
            }
            // Too few bytes for the next frame: the decoder waits for more and ends there.
            _ => return Ok(size),
        }
    }
}

/// Decompresses an Arrow message's payload in place (as the SDK would: into a buffer of the
/// stated uncompressed size) once that size is one LZ4 can reach, and checks the lengths of
/// the Arrow IPC messages the reader will take from it.
pub fn unpack_arrow(msg: &mut ArrowMsg) -> Result<(), String> {
    if msg.compression() == Compression::Lz4 {
        let most = LZ4_MAX_RATIO.saturating_mul(msg.payload.len() as u64 + 1);
        if msg.uncompressed_size > most {
            return Err(format!(
                "an Arrow message claims {} bytes uncompressed from {} compressed",
                msg.uncompressed_size,
                msg.payload.len()
            ));
        }
        let mut plain = vec![0u8; msg.uncompressed_size as usize];
        lz4_flex::block::decompress_into(&msg.payload, &mut plain)
            .map_err(|e| format!("an Arrow message does not decompress: {e}"))?;
        msg.payload = plain.into();
        msg.compression = Compression::None as i32;
    }
    check_ipc(&msg.payload)
}

/// Walks an Arrow IPC stream as the reader takes it — the schema, then messages up to the first
/// record batch — checking that each metadata and body length fits in what follows.
fn check_ipc(stream: &[u8]) -> Result<(), String> {
    const CONTINUATION: [u8; 4] = [0xff; 4];
    let mut rest = stream;
    loop {
        // The reader's end of stream: no bytes, or a zero metadata length.
        let Some((word, after)) = rest.split_first_chunk::<4>() else {
            return Ok(());
        };
        let (length, after) = if *word == CONTINUATION {
            match after.split_first_chunk::<4>() {
                Some((length, after)) => (*length, after),
                None => return Ok(()),
            }
        } else {
            (*word, after)
        };
        let meta_len = i32::from_le_bytes(length);
        if meta_len == 0 {
            return Ok(());
        }
        let meta = usize::try_from(meta_len)
            .ok()
            .and_then(|n| after.get(..n))
            .ok_or_else(|| {
                format!(
                    "an Arrow IPC message claims {meta_len} bytes of metadata; {} follow",
                    after.len()
                )
            })?;
        let message = root_as_message(meta)
            .map_err(|e| format!("an Arrow IPC message's metadata is damaged: {e}"))?;
        let body_len = message.bodyLength();
        let after = &after[meta.len()..];
        rest = usize::try_from(body_len)
            .ok()
            .and_then(|n| after.get(n..))
            .ok_or_else(|| {
                format!(
                    "an Arrow IPC message claims a body of {body_len} bytes; {} follow",
                    after.len()
                )
            })?;
        if message.header_type() == IpcHeader::RecordBatch {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(kind: u64, len: u64, payload: usize) -> Vec<u8> {
        let mut out = kind.to_le_bytes().to_vec();
        out.extend(len.to_le_bytes());
        out.extend(vec![7u8; payload]);
        out
    }

    fn prefix_of(bytes: &[u8]) -> u64 {
        let path = std::env::temp_dir().join(format!("peridyn-bounds-{}.rrd", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        let mut file = File::open(&path).unwrap();
        let prefix = decodable_prefix(&mut file, bytes.len() as u64).unwrap();
        std::fs::remove_file(&path).unwrap();
        prefix
    }

    #[test]
    fn the_decoder_sees_the_bytes_before_a_message_longer_than_the_file() {
        let mut rrd = b"RRF2\0\0\0\0\x01\x02\0\0".to_vec();
        rrd.extend(message(1, 4, 4));
        let whole = rrd.len() as u64;
        assert_eq!(prefix_of(&rrd), whole);
        // A flipped high bit of a length, and a file cut inside a message.
        let mut flipped = rrd.clone();
        flipped.extend(message(2, 1 << 62, 100));
        assert_eq!(prefix_of(&flipped), whole);
        let mut cut = rrd.clone();
        cut.extend(message(2, 100, 99));
        assert_eq!(prefix_of(&cut), whole);
        // An end marker, the stream footer, and a second stream concatenated.
        let mut two = rrd.clone();
        two.extend(message(0, 0, 0));
        two.extend([0u8; 32]);
        two.extend(&rrd);
        let two_len = two.len() as u64;
        two.extend(message(2, u64::MAX, 8));
        assert_eq!(prefix_of(&two), two_len);
        // An unknown kind is taken for a stream header, as the decoder does.
        let mut resync = rrd.clone();
        resync.extend(b"RRF2\0\0\0\0\x01\x02\0\0");
        resync.extend(message(2, 1 << 40, 0));
        assert_eq!(prefix_of(&resync), resync.len() as u64 - 16);
    }

    #[test]
    fn ipc_lengths_must_fit_in_what_follows() {
        let marker = [0xff_u8; 4];
        let mut meta = marker.to_vec();
        meta.extend(i32::MAX.to_le_bytes());
        meta.extend([0u8; 64]);
        assert!(
            check_ipc(&meta)
                .unwrap_err()
                .contains("claims 2147483647 bytes of metadata; 64 follow")
        );
        let mut negative = marker.to_vec();
        negative.extend((-8i32).to_le_bytes());
        assert!(
            check_ipc(&negative)
                .unwrap_err()
                .contains("claims -8 bytes")
        );
        // The end-of-stream marker, and nothing at all.
        let mut end = marker.to_vec();
        end.extend(0i32.to_le_bytes());
        assert_eq!(check_ipc(&end), Ok(()));
        assert_eq!(check_ipc(&[]), Ok(()));
    }

    #[test]
    fn an_uncompressed_size_lz4_cannot_reach_is_refused_before_allocating() {
        let mut msg = ArrowMsg {
            compression: Compression::Lz4 as i32,
            uncompressed_size: 1 << 50,
            payload: vec![0u8; 1000].into(),
            ..ArrowMsg::default()
        };
        let e = unpack_arrow(&mut msg).unwrap_err();
        assert!(
            e.contains("claims 1125899906842624 bytes uncompressed from 1000"),
            "{e}"
        );
        msg.uncompressed_size = 10;
        let e = unpack_arrow(&mut msg).unwrap_err();
        assert!(e.contains("does not decompress"), "{e}");
    }
}
