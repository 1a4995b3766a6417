//! Image coding shared by the simulator, the bridge and the perception node.
//!
//! JPEGs are written the way Unity's `EncodeToJPG()` writes the simulator's camera frames
//! (JFIF, IJG quality 75, 4:2:0) and read with `zune-jpeg` into RGB buffers. [`text`] and
//! [`shapes`] draw on RGB images, for the map pictures; [`message`] turns them into
//! `sensor_msgs/Image` messages and back.

pub mod message;
pub mod shapes;
pub mod text;

use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

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
    #[error("corrupt JPEG: {0}")]
    Corrupt(String),
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

/// JPEG quality of Unity's `Texture2D.EncodeToJPG()` default.
pub const UNITY_JPEG_QUALITY: u8 = 75;

/// The start-of-image marker every JPEG begins with.
const START_OF_IMAGE: [u8; 2] = [0xFF, 0xD8];
/// The end-of-image marker every complete JPEG ends with.
const END_OF_IMAGE: [u8; 2] = [0xFF, 0xD9];

/// Checks the JPEG markers and header and returns the image size, without decoding the pixels.
pub fn jpeg_dimensions(jpeg: &[u8]) -> Result<(usize, usize), ImageError> {
    if jpeg.starts_with(&START_OF_IMAGE) && !jpeg.ends_with(&END_OF_IMAGE) {
        return Err(ImageError::Truncated);
    }
    read_header(jpeg, DecoderOptions::default()).map(|(_, size)| size)
}

/// Checks that the JPEG header describes a `width` x `height` image.
pub fn check_jpeg(jpeg: &[u8], width: usize, height: usize) -> Result<(), ImageError> {
    expect_size(jpeg_dimensions(jpeg)?, (width, height))
}

/// Decodes a `width` x `height` JPEG into `out` (reusing its buffer), as RGB. The size in the
/// header is checked before the pixel buffer is sized, so a small JPEG that claims a huge image
/// costs no memory.
pub fn decode_jpeg_into(jpeg: &[u8], width: usize, height: usize, out: &mut RgbImage) -> Result<(), ImageError> {
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB).set_strict_mode(true);
    let (mut decoder, size) = read_header(jpeg, options)?;
    expect_size(size, (width, height))?;
    out.width = width;
    out.height = height;
    out.data.resize(width * height * 3, 0);
    decoder.decode_into(&mut out.data).map_err(|e| ImageError::Corrupt(format!("{e:?}")))
}

/// Decodes a `width` x `height` JPEG into a new RGB image.
pub fn decode_jpeg(jpeg: &[u8], width: usize, height: usize) -> Result<RgbImage, ImageError> {
    let mut image = RgbImage::default();
    decode_jpeg_into(jpeg, width, height, &mut image)?;
    Ok(image)
}

/// A JPEG decoder reading from a byte slice.
type HeaderDecoder<'a> = JpegDecoder<ZCursor<&'a [u8]>>;

/// A decoder past the JPEG's headers, and the image size they give. The decoder's own size
/// limits are lifted to the format's 16-bit maximum, so that [`expect_size`] names any size.
fn read_header(jpeg: &[u8], options: DecoderOptions) -> Result<(HeaderDecoder<'_>, (usize, usize)), ImageError> {
    if !jpeg.starts_with(&START_OF_IMAGE) {
        return Err(ImageError::NotJpeg(jpeg.len()));
    }
    let options = options.set_max_width(usize::from(u16::MAX)).set_max_height(usize::from(u16::MAX));
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
    decoder.decode_headers().map_err(|e| ImageError::Corrupt(format!("{e:?}")))?;
    let size = decoder.dimensions().ok_or_else(|| ImageError::Corrupt("no frame header".into()))?;
    Ok((decoder, size))
}

/// Checks an image size (width, height) against the expected one.
fn expect_size(size: (usize, usize), expected: (usize, usize)) -> Result<(), ImageError> {
    if size != expected {
        let ((width, height), (expected_width, expected_height)) = (size, expected);
        return Err(ImageError::WrongSize { width, height, expected_width, expected_height });
    }
    Ok(())
}

/// Encodes RGB as a baseline JFIF JPEG with 4:2:0 chroma subsampling at `quality`.
pub fn encode_jpeg(image: &RgbImage, quality: u8) -> Result<Vec<u8>, ImageError> {
    let mut out = Vec::with_capacity(8 * 1024);
    encode_jpeg_into(image, quality, &mut out)?;
    Ok(out)
}

/// Like [`encode_jpeg`], appending to `out` (cleared first).
pub fn encode_jpeg_into(image: &RgbImage, quality: u8, out: &mut Vec<u8>) -> Result<(), ImageError> {
    out.clear();
    let width = u16::try_from(image.width).map_err(|_| ImageError::Encode("width over 65535".into()))?;
    let height = u16::try_from(image.height).map_err(|_| ImageError::Encode("height over 65535".into()))?;
    let mut encoder = jpeg_encoder::Encoder::new(&mut *out, quality);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
    encoder
        .encode(&image.data, width, height, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| ImageError::Encode(e.to_string()))
}

/// Reads an 8-bit grayscale, RGB or RGBA PNG as RGB.
pub fn decode_png(bytes: &[u8]) -> Result<RgbImage, ImageError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(|e| ImageError::Corrupt(format!("PNG: {e}")))?;
    let mut buffer = vec![0; reader.output_buffer_size().unwrap_or_default()];
    let info = reader.next_frame(&mut buffer).map_err(|e| ImageError::Corrupt(format!("PNG: {e}")))?;
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

/// Encodes RGB as a PNG.
pub fn encode_png(image: &RgbImage) -> Result<Vec<u8>, ImageError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, image.width as u32, image.height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| ImageError::Encode(e.to_string()))?;
    writer.write_image_data(&image.data).map_err(|e| ImageError::Encode(e.to_string()))?;
    writer.finish().map_err(|e| ImageError::Encode(e.to_string()))?;
    Ok(out)
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
    fn corrupt_and_truncated_jpegs_are_named() {
        let jpeg = encode_jpeg(&gradient(64, 32), 75).unwrap();
        assert_eq!(jpeg_dimensions(b"hello"), Err(ImageError::NotJpeg(5)));
        assert_eq!(jpeg_dimensions(&jpeg[..jpeg.len() / 2]), Err(ImageError::Truncated));
        assert!(matches!(check_jpeg(&jpeg, 320, 160), Err(ImageError::WrongSize { width: 64, .. })));
        let mut garbage = jpeg.clone();
        let len = garbage.len();
        garbage[20..len - 2].fill(0xFF);
        assert!(decode_jpeg(&garbage, 64, 32).is_err());
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
    fn png_round_trip() {
        let image = gradient(20, 10);
        assert_eq!(decode_png(&encode_png(&image).unwrap()).unwrap(), image);
    }

    /// Fuzz targets: a mutated JPEG (flipped, inserted or removed bytes, truncated) is checked and
    /// decoded without panicking, and its pixel buffer is only sized when the header gives the
    /// expected size.
    mod fuzz {
        use proptest::prelude::*;
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
        }
    }
}
