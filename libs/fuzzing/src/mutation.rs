//! Byte-level mutations of a valid input: flipped bits, inserted and removed bytes, truncation, a
//! PNG header that lies about its size.

use proptest::prelude::*;

/// One edit of a byte string; positions are taken modulo its length.
#[derive(Debug, Clone)]
pub enum Edit {
    /// XOR the byte at `at` with `mask`.
    Flip {
        /// Position.
        at: usize,
        /// Bits to flip.
        mask: u8,
    },
    /// Insert `byte` before position `at`.
    Insert {
        /// Position.
        at: usize,
        /// The new byte.
        byte: u8,
    },
    /// Remove the byte at `at`.
    Remove {
        /// Position.
        at: usize,
    },
    /// Keep only the first `at` bytes.
    Truncate {
        /// New length.
        at: usize,
    },
}

impl Edit {
    /// Applies the edit to `bytes`.
    pub fn apply(&self, bytes: &mut Vec<u8>) {
        let len = bytes.len();
        match *self {
            Edit::Flip { at, mask } if len > 0 => bytes[at % len] ^= mask,
            Edit::Insert { at, byte } => bytes.insert(at % (len + 1), byte),
            Edit::Remove { at } if len > 0 => {
                bytes.remove(at % len);
            }
            Edit::Truncate { at } => bytes.truncate(at % (len + 1)),
            Edit::Flip { .. } | Edit::Remove { .. } => {}
        }
    }
}

/// A random edit, truncation being the rarest.
pub fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), 1..=u8::MAX).prop_map(|(at, mask)| Edit::Flip { at, mask }),
        2 => (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Edit::Insert { at, byte }),
        2 => any::<usize>().prop_map(|at| Edit::Remove { at }),
        1 => any::<usize>().prop_map(|at| Edit::Truncate { at }),
    ]
}

/// `seed` after one to eight random edits.
pub fn mutated_bytes(seed: Vec<u8>) -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(edit(), 1..=8).prop_map(move |edits| {
        let mut bytes = seed.clone();
        edits.iter().for_each(|edit| edit.apply(&mut bytes));
        bytes
    })
}

/// One of `seeds` after random byte edits, as text (invalid UTF-8 becomes U+FFFD).
pub fn mutated_text(seeds: Vec<String>) -> impl Strategy<Value = String> {
    proptest::sample::select(seeds)
        .prop_flat_map(|seed| mutated_bytes(seed.into_bytes()))
        .prop_map(|bytes| String::from_utf8_lossy(&bytes).into_owned())
}

/// `png` with the size in its header replaced by `width` x `height`, its checksum mended: a file
/// that claims an image far larger than the rows it holds.
pub fn with_png_size(png: &[u8], width: u32, height: u32) -> Vec<u8> {
    const IHDR_DATA: std::ops::Range<usize> = 16..29;
    let mut patched = png.to_vec();
    patched[16..20].copy_from_slice(&width.to_be_bytes());
    patched[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = png_crc32(&patched[IHDR_DATA.start - 4..IHDR_DATA.end]);
    patched[IHDR_DATA.end..IHDR_DATA.end + 4].copy_from_slice(&crc.to_be_bytes());
    patched
}

/// The CRC-32 a PNG chunk ends with, over its type and data.
fn png_crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edits_stay_in_bounds() {
        let mut bytes = b"abc".to_vec();
        Edit::Flip { at: 4, mask: 0x20 }.apply(&mut bytes);
        Edit::Insert { at: 7, byte: b'!' }.apply(&mut bytes);
        Edit::Remove { at: 3 }.apply(&mut bytes);
        assert_eq!(bytes, b"aBc".to_vec());
        Edit::Truncate { at: 2 }.apply(&mut bytes);
        assert_eq!(bytes, b"aB".to_vec());
        let mut empty = Vec::new();
        Edit::Flip { at: 1, mask: 1 }.apply(&mut empty);
        Edit::Remove { at: 1 }.apply(&mut empty);
        assert!(empty.is_empty());
    }
}
