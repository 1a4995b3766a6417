//! Image coding shared by the simulator, the bridge and the perception node.
//!
//! JPEGs are written the way Unity's `EncodeToJPG()` writes the simulator's camera frames
//! (JFIF, IJG quality 75, 4:2:0) and read into RGB buffers with libjpeg-turbo ([`jpeg`]), PNGs
//! with the `png` crate. [`text`] and [`shapes`] draw on RGB images, for the map pictures;
//! [`message`] turns them into `sensor_msgs/Image` messages and back.

mod jpeg;
pub mod message;
pub mod shapes;
pub mod text;

pub use jpeg::{
    UNITY_JPEG_QUALITY, check_jpeg, decode_jpeg, decode_jpeg_into, decode_jpeg_rows_into, encode_jpeg,
    encode_jpeg_into, jpeg_dimensions,
};

/// An 8-bit RGB image, row-major, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height * 3` bytes.
    pub data: Vec<u8>,
}

impl RgbImage {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        RgbImage { width, height, data: vec![0; width * height * 3] }
    }

    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let at = (y * self.width + x) * 3;
        [self.data[at], self.data[at + 1], self.data[at + 2]]
    }

    /// Sets the pixel at column `x`, row `y`.
    pub fn set_pixel(&mut self, x: usize, y: usize, rgb: [u8; 3]) {
        let at = (y * self.width + x) * 3;
        self.data[at..at + 3].copy_from_slice(&rgb);
    }
}

/// Errors of the codecs, naming what was wrong with the input.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ImageError {
    /// The bytes do not start with a JPEG start-of-image marker.
    #[error("not a JPEG (no FF D8 start-of-image marker, {0} bytes)")]
    NotJpeg(usize),
    /// The JPEG does not end with an end-of-image marker (truncated).
    #[error("truncated JPEG (no FF D9 end-of-image marker)")]
    Truncated,
    /// The decoder rejected the data.
    #[error("cannot decode the {format}: {reason}")]
    Corrupt {
        /// What was read: `"JPEG"` or `"PNG"`.
        format: &'static str,
        /// The decoder's words.
        reason: String,
    },
    /// The image is not the expected size.
    #[error("image is {width}x{height}, expected {expected_width}x{expected_height}")]
    WrongSize {
        /// Actual width.
        width: usize,
        /// Actual height.
        height: usize,
        /// Expected width.
        expected_width: usize,
        /// Expected height.
        expected_height: usize,
    },
    /// Encoding failed.
    #[error("cannot encode the image: {0}")]
    Encode(String),
}

/// The error of a PNG that cannot be read.
fn png_error(error: png::DecodingError) -> ImageError {
    ImageError::Corrupt { format: "PNG", reason: error.to_string() }
}

/// Most pixels a PNG may have: its header is checked before any row is decoded, so that a small
/// file claiming a huge image costs nothing.
pub const MAX_PNG_PIXELS: u64 = 1 << 22;

/// Largest image file read from a path, bytes.
pub const MAX_IMAGE_FILE_BYTES: u64 = 16 << 20;

/// The PNG's reader, refused when its header claims more than [`MAX_PNG_PIXELS`].
fn png_reader(
    bytes: &[u8],
    transformations: png::Transformations,
) -> Result<png::Reader<std::io::Cursor<&[u8]>>, ImageError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(transformations);
    let reader = decoder.read_info().map_err(png_error)?;
    let (width, height) = (reader.info().width, reader.info().height);
    if u64::from(width) * u64::from(height) > MAX_PNG_PIXELS {
        let reason = format!("its header says {width}x{height} pixels, more than the {MAX_PNG_PIXELS} accepted");
        return Err(ImageError::Corrupt { format: "PNG", reason });
    }
    Ok(reader)
}

/// Reads an 8-bit grayscale, RGB or RGBA PNG as RGB.
pub fn decode_png(bytes: &[u8]) -> Result<RgbImage, ImageError> {
    let mut reader = png_reader(bytes, png::Transformations::EXPAND | png::Transformations::STRIP_16)?;
    let mut buffer = vec![0; reader.output_buffer_size().unwrap_or_default()];
    let info = reader.next_frame(&mut buffer).map_err(png_error)?;
    let (width, height) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let mut image = RgbImage::new(width, height);
    for (pixel, source) in image.data.chunks_exact_mut(3).zip(buffer.chunks_exact(channels)) {
        match channels {
            1 | 2 => pixel.fill(source[0]),
            _ => pixel.copy_from_slice(&source[..3]),
        }
    }
    Ok(image)
}

/// A greyscale image of 16-bit samples, row-major (e.g. a survey of heights).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Gray16Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` samples.
    pub data: Vec<u16>,
}

/// Reads a 16-bit greyscale PNG with its samples as they are (no scaling to 8 bits).
pub fn decode_png_gray16(bytes: &[u8]) -> Result<Gray16Image, ImageError> {
    let mut reader = png_reader(bytes, png::Transformations::IDENTITY)?;
    let info = reader.info();
    let (color, depth, width, height) = (info.color_type, info.bit_depth, info.width, info.height);
    let corrupt = |reason: String| ImageError::Corrupt { format: "PNG", reason };
    if color != png::ColorType::Grayscale || depth != png::BitDepth::Sixteen {
        return Err(corrupt(format!("it is {color:?} with {depth:?} bits, expected 16-bit greyscale")));
    }
    let mut buffer = vec![0; reader.output_buffer_size().unwrap_or_default()];
    reader.next_frame(&mut buffer).map_err(png_error)?;
    let data = buffer.chunks_exact(2).map(|pair| u16::from_be_bytes([pair[0], pair[1]])).collect();
    Ok(Gray16Image { width: width as usize, height: height as usize, data })
}

/// Encodes a 16-bit greyscale image as a PNG.
pub fn encode_png_gray16(image: &Gray16Image) -> Result<Vec<u8>, ImageError> {
    let bytes: Vec<u8> = image.data.iter().flat_map(|v| v.to_be_bytes()).collect();
    encode_png_samples((image.width, image.height), png::ColorType::Grayscale, png::BitDepth::Sixteen, &bytes)
}

/// Encodes RGB as a PNG.
pub fn encode_png(image: &RgbImage) -> Result<Vec<u8>, ImageError> {
    encode_png_samples((image.width, image.height), png::ColorType::Rgb, png::BitDepth::Eight, &image.data)
}

/// A PNG of `width` x `height` pixels whose samples, in PNG byte order, are `bytes`.
fn encode_png_samples(
    (width, height): (usize, usize),
    color: png::ColorType,
    depth: png::BitDepth,
    bytes: &[u8],
) -> Result<Vec<u8>, ImageError> {
    let encode_error = |e: png::EncodingError| ImageError::Encode(e.to_string());
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width as u32, height as u32);
    encoder.set_color(color);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header().map_err(encode_error)?;
    writer.write_image_data(bytes).map_err(encode_error)?;
    writer.finish().map_err(encode_error)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip() {
        let mut image = RgbImage::new(20, 10);
        for (i, byte) in image.data.iter_mut().enumerate() {
            *byte = (i * 7 % 251) as u8;
        }
        assert_eq!(decode_png(&encode_png(&image).unwrap()).unwrap(), image);
    }

    #[test]
    fn sixteen_bit_grey_keeps_its_samples_and_other_pngs_are_refused() {
        let image = Gray16Image { width: 3, height: 2, data: vec![0, 1, 255, 256, 3870, u16::MAX] };
        assert_eq!(decode_png_gray16(&encode_png_gray16(&image).unwrap()).unwrap(), image);
        let rgb = encode_png(&RgbImage::new(2, 2)).unwrap();
        let error = decode_png_gray16(&rgb).unwrap_err().to_string();
        assert!(error.contains("expected 16-bit greyscale"), "{error}");
    }

    #[test]
    fn a_png_that_cannot_be_read_is_named_a_png() {
        let error = decode_png(b"not a PNG at all").unwrap_err();
        assert!(error.to_string().starts_with("cannot decode the PNG: "), "{error}");
    }

    #[test]
    fn a_png_whose_header_claims_a_huge_image_is_refused_before_its_rows_are_read() {
        use rover_fuzzing::mutation::with_png_size;
        let rgb = encode_png(&RgbImage::new(64, 64)).unwrap();
        assert_eq!(decode_png(&with_png_size(&rgb, 64, 64)).unwrap(), RgbImage::new(64, 64), "the mend keeps it valid");
        let huge = with_png_size(&rgb, 100_000, 100_000);
        let error = decode_png(&huge).unwrap_err().to_string();
        assert!(error.contains("100000x100000") && error.contains("more than"), "{error}");
        let grey = encode_png_gray16(&Gray16Image { width: 4, height: 4, data: vec![7; 16] }).unwrap();
        let error = decode_png_gray16(&with_png_size(&grey, 1 << 20, 8)).unwrap_err().to_string();
        assert!(error.contains("1048576x8"), "{error}");
    }

    /// A survey and a map PNG, their bytes mutated: read or refused, never a panic, and what is
    /// read is whole.
    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_bytes;

        use super::*;

        fn small_survey() -> Vec<u8> {
            let data = (0..12 * 9).map(|i| (i * 37) as u16).collect();
            encode_png_gray16(&Gray16Image { width: 12, height: 9, data }).unwrap()
        }

        fn small_map() -> Vec<u8> {
            let mut image = RgbImage::new(10, 7);
            image.data.iter_mut().enumerate().for_each(|(i, byte)| *byte = (i * 11) as u8);
            encode_png(&image).unwrap()
        }

        proptest! {
            #[test]
            fn fuzz_png_gray16_mutated_bytes(png in mutated_bytes(small_survey())) {
                if let Ok(image) = decode_png_gray16(&png) {
                    prop_assert_eq!(image.data.len(), image.width * image.height);
                }
            }

            #[test]
            fn fuzz_png_rgb_mutated_bytes(png in mutated_bytes(small_map())) {
                if let Ok(image) = decode_png(&png) {
                    prop_assert_eq!(image.data.len(), image.width * image.height * 3);
                    prop_assert!((image.width * image.height) as u64 <= MAX_PNG_PIXELS);
                }
            }
        }
    }
}
