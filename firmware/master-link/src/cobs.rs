//! Consistent Overhead Byte Stuffing (COBS), allocation- and panic-free.
//!
//! Implemented locally (instead of pulling the `cobs` crate) so that every
//! buffer access is bounds-checked with `get`/`get_mut` and no code path can
//! panic, whatever the input bytes are.
//!
//! The encoded form never contains `0x00`; the frame delimiter `0x00` is
//! *not* written by [`encode`] and must *not* be passed to [`decode_in_place`].

/// Upper bound of the encoded length of `raw_len` bytes (without delimiter).
pub const fn max_encoded_len(raw_len: usize) -> usize {
    raw_len + raw_len / 254 + 1
}

/// COBS-encodes `src` into `dst`. Returns the number of bytes written
/// (without delimiter), or `None` if `dst` is too small.
pub fn encode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let mut code_idx: usize = 0;
    let mut write: usize = 1;
    let mut code: u8 = 1;
    for &byte in src {
        if byte == 0 {
            *dst.get_mut(code_idx)? = code;
            code_idx = write;
            write = write.checked_add(1)?;
            code = 1;
        } else {
            *dst.get_mut(write)? = byte;
            write = write.checked_add(1)?;
            code = code.wrapping_add(1);
            if code == 0xFF {
                *dst.get_mut(code_idx)? = code;
                code_idx = write;
                write = write.checked_add(1)?;
                code = 1;
            }
        }
    }
    *dst.get_mut(code_idx)? = code;
    Some(write)
}

/// Decodes a COBS block (without delimiter) in place. Returns the decoded
/// length (the decoded bytes are `buf[..len]`), or `None` if the input is not
/// valid COBS (a `0x00` byte inside, or a code byte pointing past the end).
pub fn decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let len = buf.len();
    let mut read: usize = 0;
    let mut write: usize = 0;
    while read < len {
        let code = *buf.get(read)?;
        if code == 0 {
            return None;
        }
        read += 1;
        let run = usize::from(code) - 1;
        if run > len - read {
            return None;
        }
        for _ in 0..run {
            let byte = *buf.get(read)?;
            if byte == 0 {
                return None;
            }
            // `write < read` always holds, so this never clobbers unread input.
            *buf.get_mut(write)? = byte;
            read += 1;
            write += 1;
        }
        if code != 0xFF && read < len {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn roundtrip(src: &[u8]) {
        let mut enc = [0u8; 600];
        let n = encode(src, &mut enc).unwrap();
        assert!(n <= max_encoded_len(src.len()));
        assert!(!enc[..n].contains(&0));
        let m = decode_in_place(&mut enc[..n]).unwrap();
        assert_eq!(&enc[..m], src);
    }

    /// Known vectors from the COBS paper / Wikipedia.
    #[test]
    fn cobs_known_vectors() {
        let mut out = [0u8; 16];
        let n = encode(&[0x00], &mut out).unwrap();
        assert_eq!(&out[..n], &[0x01, 0x01]);
        let n = encode(&[0x00, 0x00], &mut out).unwrap();
        assert_eq!(&out[..n], &[0x01, 0x01, 0x01]);
        let n = encode(&[0x11, 0x22, 0x00, 0x33], &mut out).unwrap();
        assert_eq!(&out[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let n = encode(&[], &mut out).unwrap();
        assert_eq!(&out[..n], &[0x01]);
    }

    /// Encoding then decoding gives back the input, including runs of 254+
    /// non-zero bytes (0xFF code blocks) and zeros at the edges.
    #[test]
    fn cobs_roundtrip_edge_cases() {
        roundtrip(&[]);
        roundtrip(&[0]);
        roundtrip(&[1; 253]);
        roundtrip(&[1; 254]);
        roundtrip(&[1; 255]);
        roundtrip(&[7; 508]);
        let mut v = [0u8; 300];
        for (i, b) in v.iter_mut().enumerate() {
            *b = (i % 7) as u8;
        }
        roundtrip(&v);
    }

    /// A too-small destination is reported as `None`, never a panic.
    #[test]
    fn cobs_encode_buffer_too_small() {
        let mut out = [0u8; 3];
        assert_eq!(encode(&[1, 2, 3], &mut out), None);
        assert_eq!(encode(&[1, 2, 3], &mut []), None);
    }

    /// Invalid COBS (embedded zero, code past end) is rejected.
    #[test]
    fn cobs_decode_rejects_garbage() {
        assert_eq!(decode_in_place(&mut [0x05, 1, 2]), None);
        assert_eq!(decode_in_place(&mut [0x03, 0, 2]), None);
        assert_eq!(decode_in_place(&mut [0x00]), None);
        assert_eq!(decode_in_place(&mut []), Some(0));
    }
}
