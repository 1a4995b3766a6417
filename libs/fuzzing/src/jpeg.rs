//! Progressive JPEGs of many scans, written by hand: valid files that are costly to decode.

/// A progressive 8x8 greyscale JPEG, all mid-grey, whose DC and each of the 63 AC coefficients
/// are sent with successive approximation, `refinement_bits` (at most 13) bits after the first
/// scan: `64 * (refinement_bits + 1)` scans in all.
pub fn progressive_grey_8x8(refinement_bits: u8) -> Vec<u8> {
    assert!(refinement_bits <= 13, "JPEG allows at most 13 refinement bits");
    let mut jpeg = vec![0xFF, 0xD8];
    segment(&mut jpeg, 0xDB, &[[0u8].as_slice(), &[1; 64]].concat());
    segment(&mut jpeg, 0xC2, &[8, 0, 8, 0, 8, 1, 1, 0x11, 0]);
    for table_class in [0x00, 0x10] {
        let mut one_code = vec![table_class, 1];
        one_code.extend([0; 15]);
        one_code.push(0);
        segment(&mut jpeg, 0xC4, &one_code);
    }
    for coefficient in 0..64u8 {
        for low_bit in (0..=refinement_bits).rev() {
            let high_bit = if low_bit == refinement_bits { 0 } else { low_bit + 1 };
            segment(&mut jpeg, 0xDA, &[1, 1, 0, coefficient, coefficient, (high_bit << 4) | low_bit]);
            jpeg.push(0x7F);
        }
    }
    jpeg.extend([0xFF, 0xD9]);
    jpeg
}

/// Appends the marker segment `FF marker`, its length and `payload`.
fn segment(jpeg: &mut Vec<u8>, marker: u8, payload: &[u8]) {
    jpeg.extend([0xFF, marker]);
    jpeg.extend(((payload.len() + 2) as u16).to_be_bytes());
    jpeg.extend_from_slice(payload);
}
