//! Authenticated frames: a pre-shared 32-byte key and the truncated HMAC-SHA256 tag every
//! frame carries when the link has one.
//!
//! The tag is the first [`TAG_LEN`] bytes of HMAC-SHA256(key, version | session | sequence
//! | body) (RFC 2104, FIPS 198-1), placed between the body and the CRC. A receiver with a
//! key drops every frame whose tag does not verify (`bad_tag`); the comparison is
//! constant-time. Without a key a link works as on a desk: no tag, and frames with one
//! are malformed (trailing bytes after the body).
//!
//! **Why 8 bytes.** A forger must guess a 64-bit tag: on a 1 Mbaud line (at most about
//! 4,000 frames a second) that takes about 2^63 / 4000 s, some 70 million years, on average,
//! and every wrong guess is counted. The tag also has to fit the frame: the largest status
//! report fills 252 of the 253 un-stuffed bytes with it.
//!
//! **The key's state.** [`LinkKey`] keeps the HMAC with the key's inner and outer pads
//! already absorbed, so a frame costs the hash of its own bytes (two SHA-256 compressions
//! for any frame up to 55 bytes of header and body, one more per further 64 bytes), not the
//! key's pads again.

use hmac::{Hmac, Mac};
use sha2::Sha256;

/// Bytes of the truncated HMAC-SHA256 tag of an authenticated frame.
pub const TAG_LEN: usize = 8;
/// Bytes of a link key.
pub const KEY_LEN: usize = 32;

/// A pre-shared link key, ready to tag frames. Its `Debug` output never shows the key.
#[derive(Clone)]
pub struct LinkKey {
    mac: Hmac<Sha256>,
}

impl core::fmt::Debug for LinkKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("LinkKey(..)")
    }
}

/// Two keys are equal when they tag alike (compared by the tags of a fixed message, which
/// say nothing of the keys).
impl PartialEq for LinkKey {
    fn eq(&self, other: &Self) -> bool {
        self.tag(b"rspr-link-key-eq") == other.tag(b"rspr-link-key-eq")
    }
}

/// Why a key's text was refused ([`LinkKey::from_hex`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum KeyError {
    /// Not 64 hexadecimal digits (surrounding white space allowed).
    Format,
}

impl LinkKey {
    /// The key `bytes`.
    pub fn new(bytes: &[u8; KEY_LEN]) -> Self {
        LinkKey {
            mac: padded_mac(bytes),
        }
    }

    /// The key from its 64 hexadecimal digits (a key file's content; white space around
    /// them is ignored).
    pub fn from_hex(text: &str) -> Result<Self, KeyError> {
        let mut bytes = [0u8; KEY_LEN];
        let digits = text.trim().as_bytes();
        if digits.len() != 2 * KEY_LEN {
            return Err(KeyError::Format);
        }
        for (out, pair) in bytes.iter_mut().zip(digits.chunks(2)) {
            let [hi, lo] = pair else {
                return Err(KeyError::Format);
            };
            *out = (hex(*hi).ok_or(KeyError::Format)? << 4) | hex(*lo).ok_or(KeyError::Format)?;
        }
        Ok(LinkKey::new(&bytes))
    }

    /// The tag of `content` (header and body).
    pub fn tag(&self, content: &[u8]) -> [u8; TAG_LEN] {
        let mut mac = self.mac.clone();
        mac.update(content);
        let full = mac.finalize().into_bytes();
        let mut tag = [0u8; TAG_LEN];
        for (t, b) in tag.iter_mut().zip(full.iter()) {
            *t = *b;
        }
        tag
    }

    /// `tag` is the tag of `content` (constant-time comparison).
    pub fn verify(&self, content: &[u8], tag: &[u8]) -> bool {
        let mut mac = self.mac.clone();
        mac.update(content);
        tag.len() == TAG_LEN && mac.verify_truncated_left(tag).is_ok()
    }
}

/// HMAC-SHA256 keyed with `key`: a key shorter than SHA-256's 64-byte block is padded with
/// zeros (RFC 2104, section 2), which is what the fixed-size constructor takes.
fn padded_mac(key: &[u8]) -> Hmac<Sha256> {
    let mut block = [0u8; 64];
    for (b, k) in block.iter_mut().zip(key) {
        *b = *k;
    }
    <Hmac<Sha256> as hmac::digest::KeyInit>::new(&block.into())
}

const fn hex(d: u8) -> Option<u8> {
    match d {
        b'0'..=b'9' => Some(d - b'0'),
        b'a'..=b'f' => Some(d - b'a' + 10),
        b'A'..=b'F' => Some(d - b'A' + 10),
        _ => None,
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// The tag is the HMAC-SHA256 of the content (the variable-length constructor as the
    /// reference), truncated; a changed content or a short tag does not verify.
    #[test]
    fn tag_is_the_truncated_hmac_sha256() {
        let key = [0x0bu8; KEY_LEN];
        let k = LinkKey::new(&key);
        let Ok(mut reference) = <Hmac<Sha256> as Mac>::new_from_slice(&key) else {
            unreachable!("HMAC takes any key length")
        };
        reference.update(b"Hi There");
        let full = reference.finalize().into_bytes();
        assert_eq!(&k.tag(b"Hi There")[..], &full[..TAG_LEN]);
        assert!(k.verify(b"Hi There", &full[..TAG_LEN]));
        assert!(!k.verify(b"Hi There!", &full[..TAG_LEN]));
        assert!(!k.verify(b"Hi There", &full[..TAG_LEN - 1]));
    }

    /// RFC 4231 test case 1 (key 20 x 0x0b, "Hi There"): the known HMAC-SHA256 prefix.
    #[test]
    fn rfc_4231_case_1_prefix() {
        let mut mac = padded_mac(&[0x0b; 20]);
        mac.update(b"Hi There");
        let full = mac.finalize().into_bytes();
        assert_eq!(
            &full[..8],
            &[0xb0, 0x34, 0x4c, 0x61, 0xd8, 0xdb, 0x38, 0x53]
        );
    }

    /// A key file's hex: 64 digits, either case, white space around; anything else refused;
    /// `Debug` hides the key.
    #[test]
    fn hex_keys() {
        let text = "  00112233445566778899AABBCCDDEEFF00112233445566778899aabbccddeeff\n";
        let k = LinkKey::from_hex(text).map(|k| k.tag(b"x"));
        let mut bytes = [0u8; KEY_LEN];
        for (i, b) in bytes.iter_mut().enumerate() {
            *b = ((i % 16) as u8) * 0x11;
        }
        assert_eq!(k, Ok(LinkKey::new(&bytes).tag(b"x")));
        assert_eq!(LinkKey::from_hex("0011").map(|_| ()), Err(KeyError::Format));
        let bad = text.replace('F', "g");
        assert_eq!(LinkKey::from_hex(&bad).map(|_| ()), Err(KeyError::Format));
        extern crate std;
        assert_eq!(std::format!("{:?}", LinkKey::new(&bytes)), "LinkKey(..)");
    }
}
