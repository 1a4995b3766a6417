//! JPEG coding through the system's libjpeg-turbo (`csrc/jpeg.c`), the codec that OpenCV, PIL and
//! ROS's `compressed` image transport use: frames are written the way Unity's `EncodeToJPG()`
//! writes the simulator's camera frames (JFIF, IJG quality 75, 4:2:0) and read into RGB exactly as
//! the Python tools read them.

use std::ffi::{CStr, c_char, c_int, c_ulong};
use std::ops::Range;

use crate::{ImageError, RgbImage};

/// JPEG quality of Unity's `Texture2D.EncodeToJPG()` default.
pub const UNITY_JPEG_QUALITY: u8 = 75;

/// The start-of-image marker every JPEG begins with.
const START_OF_IMAGE: [u8; 2] = [0xFF, 0xD8];
/// The end-of-image marker every complete JPEG ends with.
const END_OF_IMAGE: [u8; 2] = [0xFF, 0xD9];
/// Room for the message of a failed call (libjpeg's `JMSG_LENGTH_MAX`).
const MESSAGE_BYTES: usize = 200;
/// The longest side of an image that libjpeg codes (its `JPEG_MAX_DIMENSION`), pixels.
const MAX_SIDE_PX: usize = 65_500;
/// What a call of `csrc/jpeg.c` returns when it succeeded.
const OK: c_int = 0;

unsafe extern "C" {
    fn rover_jpeg_encode(
        rgb: *const u8,
        width: c_int,
        height: c_int,
        quality: c_int,
        capacity_hint: usize,
        out: *mut *mut u8,
        out_len: *mut c_ulong,
        message: *mut c_char,
        message_len: usize,
    ) -> c_int;
    fn rover_jpeg_free(buffer: *mut u8);
    fn rover_jpeg_decode(
        jpeg: *const u8,
        len: c_ulong,
        rgb: *mut u8,
        rgb_width: c_int,
        rgb_height: c_int,
        first_row: c_int,
        end_row: c_int,
        width: *mut c_int,
        height: *mut c_int,
        message: *mut c_char,
        message_len: usize,
    ) -> c_int;
}

/// The message a failed call left in `buffer` (zeroed before the call, a NUL-terminated string
/// after it).
fn message_of(buffer: &[u8; MESSAGE_BYTES]) -> String {
    CStr::from_bytes_until_nul(buffer).map_or_else(|_| "no message".into(), |m| m.to_string_lossy().into_owned())
}

/// The width and height of an image as C ints, if a JPEG can be that size (1..=65,500 a side).
fn jpeg_size(width: usize, height: usize) -> Option<(c_int, c_int)> {
    let side = |px: usize| (1..=MAX_SIDE_PX).contains(&px).then_some(px as c_int);
    side(width).zip(side(height))
}

/// The length of `jpeg` as the C side takes it.
fn c_len(jpeg: &[u8]) -> Result<c_ulong, ImageError> {
    c_ulong::try_from(jpeg.len()).map_err(|_| jpeg_error(format!("{} bytes is more than libjpeg reads", jpeg.len())))
}

/// The error of a failed call on `jpeg`: libjpeg's message, and the size of what it read.
fn corrupt(jpeg: &[u8], message: &[u8; MESSAGE_BYTES]) -> ImageError {
    jpeg_error(format!("{} (in {} bytes)", message_of(message), jpeg.len()))
}

/// A JPEG that cannot be decoded, for `reason`.
fn jpeg_error(reason: String) -> ImageError {
    ImageError::Corrupt { format: "JPEG", reason }
}

/// Checks the JPEG markers and header and returns the image size, without decoding the pixels.
pub fn jpeg_dimensions(jpeg: &[u8]) -> Result<(usize, usize), ImageError> {
    check_markers(jpeg)?;
    decode(jpeg, None)
}

/// Where [`decode`] puts pixels: a buffer for a whole image of `size` (width, height), and the
/// rows of it to decode.
struct Pixels<'a> {
    buffer: &'a mut [u8],
    size: (usize, usize),
    rows: Range<usize>,
}

/// Reads the headers of `jpeg` and returns the image size; with `rgb`, also decodes its rows into
/// it when the JPEG has its size.
fn decode(jpeg: &[u8], rgb: Option<Pixels>) -> Result<(usize, usize), ImageError> {
    let (pixels, (rgb_width, rgb_height), rows) = match rgb {
        Some(Pixels { buffer, size, rows }) => {
            assert_eq!(buffer.len(), size.0 * size.1 * 3, "a buffer for the whole image");
            assert!(rows.start <= rows.end && rows.end <= size.1, "rows {rows:?} of an image {} high", size.1);
            (buffer.as_mut_ptr(), size, rows)
        }
        None => (std::ptr::null_mut(), (0, 0), 0..0),
    };
    let (mut width, mut height) = (0, 0);
    let mut message = [0u8; MESSAGE_BYTES];
    // SAFETY: `jpeg` is valid for its length; `pixels` is null (the header only) or holds
    // `rgb_width * rgb_height * 3` bytes (asserted), which the C side writes only for an image of
    // that size (callers pass a size the header gave, so the sides and rows fit a C int: libjpeg
    // reads at most 65,500); the outputs are valid for writes; the message buffer holds
    // `MESSAGE_BYTES`.
    let status = unsafe {
        rover_jpeg_decode(
            jpeg.as_ptr(),
            c_len(jpeg)?,
            pixels,
            rgb_width as c_int,
            rgb_height as c_int,
            rows.start as c_int,
            rows.end as c_int,
            &mut width,
            &mut height,
            message.as_mut_ptr().cast::<c_char>(),
            MESSAGE_BYTES,
        )
    };
    if status != OK {
        return Err(corrupt(jpeg, &message));
    }
    Ok((width as usize, height as usize))
}

/// A JPEG starts with the start-of-image marker and, unless cut short, ends with end-of-image.
fn check_markers(jpeg: &[u8]) -> Result<(), ImageError> {
    if !jpeg.starts_with(&START_OF_IMAGE) {
        return Err(ImageError::NotJpeg(jpeg.len()));
    }
    if !jpeg.ends_with(&END_OF_IMAGE) {
        return Err(ImageError::Truncated);
    }
    Ok(())
}

/// Checks that the JPEG header describes a `width` x `height` image.
pub fn check_jpeg(jpeg: &[u8], width: usize, height: usize) -> Result<(), ImageError> {
    expect_size(jpeg_dimensions(jpeg)?, (width, height))
}

/// Decodes a `width` x `height` JPEG into `out` (reusing its buffer), as RGB. The size in the
/// header is checked before the pixel buffer is sized, so a small JPEG that claims a huge image
/// costs no memory. Corrupt data fails the decoding (libjpeg would decode on past it).
pub fn decode_jpeg_into(jpeg: &[u8], width: usize, height: usize, out: &mut RgbImage) -> Result<(), ImageError> {
    decode_jpeg_rows_into(jpeg, width, height, 0..height, out)
}

/// Decodes rows `rows` of a `width` x `height` JPEG into their places in `out` (reusing its
/// buffer, sized for the whole image; the other rows keep whatever they held), as RGB: the same
/// pixels as in a decoding of the whole image, for less work (libjpeg only reads past the rows
/// above, and stops after the last). Corrupt data in those rows and above fails the decoding.
/// Panics if `rows` does not lie within `0..height`.
pub fn decode_jpeg_rows_into(
    jpeg: &[u8],
    width: usize,
    height: usize,
    rows: Range<usize>,
    out: &mut RgbImage,
) -> Result<(), ImageError> {
    check_jpeg(jpeg, width, height)?;
    out.width = width;
    out.height = height;
    out.data.resize(width * height * 3, 0);
    decode(jpeg, Some(Pixels { buffer: &mut out.data, size: (width, height), rows }))?;
    Ok(())
}

/// Decodes a `width` x `height` JPEG into a new RGB image.
pub fn decode_jpeg(jpeg: &[u8], width: usize, height: usize) -> Result<RgbImage, ImageError> {
    let mut image = RgbImage::default();
    decode_jpeg_into(jpeg, width, height, &mut image)?;
    Ok(image)
}

/// Checks an image size (width, height) against the expected one.
fn expect_size(size: (usize, usize), expected: (usize, usize)) -> Result<(), ImageError> {
    if size != expected {
        let ((width, height), (expected_width, expected_height)) = (size, expected);
        return Err(ImageError::WrongSize { width, height, expected_width, expected_height });
    }
    Ok(())
}

/// Encodes RGB as a baseline JFIF JPEG with 4:2:0 chroma subsampling at `quality` (1..=100).
pub fn encode_jpeg(image: &RgbImage, quality: u8) -> Result<Vec<u8>, ImageError> {
    let mut out = Vec::with_capacity(8 * 1024);
    encode_jpeg_into(image, quality, &mut out)?;
    Ok(out)
}

/// Like [`encode_jpeg`], into `out` (cleared first; its capacity is the first guess of the size).
pub fn encode_jpeg_into(image: &RgbImage, quality: u8, out: &mut Vec<u8>) -> Result<(), ImageError> {
    out.clear();
    let (width, height) = jpeg_size(image.width, image.height).ok_or_else(|| {
        ImageError::Encode(format!("a JPEG cannot be {}x{} (1..={MAX_SIDE_PX} a side)", image.width, image.height))
    })?;
    if image.data.len() != image.width * image.height * 3 {
        return Err(ImageError::Encode(format!(
            "{} bytes for a {}x{} RGB image",
            image.data.len(),
            image.width,
            image.height
        )));
    }
    let (mut buffer, mut len): (*mut u8, c_ulong) = (std::ptr::null_mut(), 0);
    let mut message = [0u8; MESSAGE_BYTES];
    // SAFETY: `image.data` holds `width * height * 3` bytes (checked above), what the C side reads;
    // the outputs are valid for writes; the message buffer holds `MESSAGE_BYTES` bytes.
    let status = unsafe {
        rover_jpeg_encode(
            image.data.as_ptr(),
            width,
            height,
            c_int::from(quality.clamp(1, 100)),
            out.capacity(),
            &mut buffer,
            &mut len,
            message.as_mut_ptr().cast::<c_char>(),
            MESSAGE_BYTES,
        )
    };
    if status != OK {
        return Err(ImageError::Encode(message_of(&message)));
    }
    // SAFETY: on success the C side hands over a buffer of `len` bytes, freed once copied.
    unsafe {
        out.extend_from_slice(std::slice::from_raw_parts(buffer, len as usize));
        rover_jpeg_free(buffer);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(width: usize, height: usize) -> RgbImage {
        let mut image = RgbImage::new(width, height);
        for y in 0..height {
            for x in 0..width {
                image.set_pixel(x, y, [(x * 255 / width) as u8, (y * 255 / height) as u8, 128]);
            }
        }
        image
    }

    #[test]
    fn jpeg_round_trip_keeps_size_and_colours() {
        let image = gradient(320, 160);
        let jpeg = encode_jpeg(&image, UNITY_JPEG_QUALITY).unwrap();
        assert!(jpeg.starts_with(&[0xFF, 0xD8, 0xFF, 0xE0]), "JFIF APP0 first");
        assert_eq!(jpeg_dimensions(&jpeg).unwrap(), (320, 160));
        let decoded = decode_jpeg(&jpeg, 320, 160).unwrap();
        assert_eq!((decoded.width, decoded.height), (320, 160));
        let max_error = image.data.iter().zip(&decoded.data).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(max_error < 16, "max error {max_error}");
    }

    #[test]
    fn frames_are_baseline_4_2_0_at_the_quality_asked() {
        let jpeg = encode_jpeg(&gradient(64, 32), UNITY_JPEG_QUALITY).unwrap();
        let start_of_frame = jpeg.windows(2).position(|w| w == [0xFF, 0xC0]).expect("a baseline frame header");
        let components = &jpeg[start_of_frame + 10..start_of_frame + 19];
        assert_eq!([components[1], components[4], components[7]], [0x22, 0x11, 0x11], "luma 2x2, chroma 1x1");
        let lower = encode_jpeg(&gradient(64, 32), 30).unwrap();
        assert!(lower.len() < jpeg.len(), "quality 30: {} bytes, 75: {}", lower.len(), jpeg.len());
    }

    #[test]
    fn a_progressive_jpeg_of_more_than_100_scans_is_refused() {
        use rover_fuzzing::jpeg::progressive_grey_8x8;

        let grey = decode_jpeg(&progressive_grey_8x8(0), 8, 8).expect("64 scans decode");
        assert!(grey.data.iter().all(|&v| v.abs_diff(128) <= 1), "mid-grey: {:?}", &grey.data[..6]);
        let error = decode_jpeg(&progressive_grey_8x8(13), 8, 8).unwrap_err();
        assert!(error.to_string().starts_with("cannot decode the JPEG: it has more than 100 scans"), "{error}");
    }

    #[test]
    fn corrupt_and_truncated_jpegs_are_named() {
        let jpeg = encode_jpeg(&gradient(64, 32), 75).unwrap();
        assert_eq!(jpeg_dimensions(b"hello"), Err(ImageError::NotJpeg(5)));
        assert_eq!(jpeg_dimensions(&jpeg[..jpeg.len() / 2]), Err(ImageError::Truncated));
        assert!(matches!(check_jpeg(&jpeg, 320, 160), Err(ImageError::WrongSize { width: 64, .. })));
        let mut garbage = jpeg.clone();
        let len = garbage.len();
        garbage[20..len - 2].fill(0xFF);
        let error = decode_jpeg(&garbage, 64, 32).unwrap_err();
        assert!(matches!(&error, ImageError::Corrupt { format: "JPEG", reason } if !reason.is_empty()), "{error}");
        let mut cut_scan = jpeg[..jpeg.len() - 40].to_vec();
        cut_scan.extend_from_slice(&END_OF_IMAGE);
        let error = decode_jpeg(&cut_scan, 64, 32).unwrap_err();
        assert!(error.to_string().starts_with("cannot decode the JPEG: Corrupt JPEG data"), "{error}");
    }

    #[test]
    fn rows_decoded_alone_are_those_of_the_whole_image_and_corrupt_data_above_them_fails() {
        let mut image = gradient(320, 160);
        let mut state = 7u32;
        for byte in &mut image.data {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *byte = byte.wrapping_add((state >> 27) as u8);
        }
        let jpeg = encode_jpeg(&image, UNITY_JPEG_QUALITY).unwrap();
        let whole = decode_jpeg(&jpeg, 320, 160).unwrap();
        let row_bytes = 320 * 3;
        for rows in [0..160, 79..142, 1..2, 15..17, 16..32, 100..160, 159..160, 40..40] {
            let mut out = RgbImage::default();
            decode_jpeg_rows_into(&jpeg, 320, 160, rows.clone(), &mut out).unwrap();
            let bytes = rows.start * row_bytes..rows.end * row_bytes;
            assert_eq!(out.data[bytes.clone()], whole.data[bytes], "rows {rows:?}");
        }
        let mut garbage = jpeg.clone();
        let len = garbage.len();
        garbage[len / 4..len - 2].fill(0xFF);
        let error = decode_jpeg_rows_into(&garbage, 320, 160, 150..160, &mut RgbImage::default()).unwrap_err();
        assert!(matches!(error, ImageError::Corrupt { .. }), "{error}");
    }

    #[test]
    fn a_jpeg_of_the_wrong_size_is_rejected_before_its_buffer_is_sized() {
        let jpeg = encode_jpeg(&gradient(64, 32), 75).unwrap();
        let mut out = RgbImage::default();
        let error = decode_jpeg_into(&jpeg, 320, 160, &mut out).unwrap_err();
        assert_eq!(error.to_string(), "image is 64x32, expected 320x160");
        assert_eq!((out.width, out.height, out.data.capacity()), (0, 0, 0));
    }

    #[test]
    fn images_no_jpeg_can_hold_are_refused() {
        assert!(matches!(encode_jpeg(&RgbImage::new(0, 10), 75), Err(ImageError::Encode(_))));
        let too_wide = encode_jpeg(&RgbImage::new(MAX_SIDE_PX + 1, 1), 75).unwrap_err();
        assert_eq!(too_wide.to_string(), "cannot encode the image: a JPEG cannot be 65501x1 (1..=65500 a side)");
        let short = RgbImage { width: 8, height: 8, data: vec![0; 10] };
        assert!(matches!(encode_jpeg(&short, 75), Err(ImageError::Encode(_))));
    }

    #[test]
    fn a_jpeg_many_times_the_first_buffer_is_written_whole() {
        let mut noise = RgbImage::new(320, 160);
        let mut state = 1u32;
        for pixel in noise.data.chunks_exact_mut(3) {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            pixel.fill((state >> 24) as u8);
        }
        let mut jpeg = Vec::new();
        encode_jpeg_into(&noise, 100, &mut jpeg).unwrap();
        assert!(jpeg.len() > 64 * 1024, "{} bytes grow a 1 kB buffer many times", jpeg.len());
        assert!(jpeg.ends_with(&END_OF_IMAGE));
        let decoded = decode_jpeg(&jpeg, 320, 160).unwrap();
        let mean_error = noise.data.iter().zip(&decoded.data).map(|(a, b)| a.abs_diff(*b) as f64).sum::<f64>()
            / noise.data.len() as f64;
        assert!(mean_error < 4.0, "grey noise at quality 100: mean error {mean_error}");
    }

    /// Fuzz targets: a mutated JPEG (flipped, inserted or removed bytes, truncated), baseline or
    /// progressive, is checked and decoded without panicking, and its pixel buffer is only sized
    /// when the header gives the expected size.
    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::jpeg::progressive_grey_8x8;
        use rover_fuzzing::mutation::mutated_bytes;

        use super::*;

        const SIZE: (usize, usize) = (16, 8);

        fn small_jpeg() -> Vec<u8> {
            encode_jpeg(&gradient(SIZE.0, SIZE.1), 75).unwrap()
        }

        proptest! {
            #[test]
            fn fuzz_jpeg_mutated_bytes(jpeg in mutated_bytes(small_jpeg())) {
                let header_size = jpeg_dimensions(&jpeg);
                prop_assert_eq!(check_jpeg(&jpeg, SIZE.0, SIZE.1).is_ok(), header_size == Ok(SIZE));
                let mut out = RgbImage::default();
                match decode_jpeg_into(&jpeg, SIZE.0, SIZE.1, &mut out) {
                    Ok(()) => prop_assert_eq!(out.data.len(), SIZE.0 * SIZE.1 * 3),
                    Err(_) => prop_assert!(out.data.capacity() == 0 || out.data.len() == SIZE.0 * SIZE.1 * 3),
                }
            }

            #[test]
            fn fuzz_progressive_jpeg_mutated_bytes(jpeg in mutated_bytes(progressive_grey_8x8(1))) {
                if let Ok(image) = decode_jpeg(&jpeg, 8, 8) {
                    prop_assert_eq!(image.data.len(), 8 * 8 * 3);
                }
            }
        }
    }
}
