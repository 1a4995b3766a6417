//! Image coding shared by the simulator, the bridge and the perception node.
//!
//! JPEGs are written the way Unity's `EncodeToJPG()` writes the simulator's camera frames
//! (JFIF, IJG quality 75, 4:2:0) and read into RGB buffers with libjpeg-turbo ([`jpeg`]), PNGs
//! with the `png` crate. [`text`] and [`shapes`] draw on RGB images, for the map pictures;
//! [`message`] turns them into `sensor_msgs/Image` messages and back.

pub mod jpeg;
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

/// Reads an 8-bit grayscale, RGB or RGBA PNG as RGB.
pub fn decode_png(bytes: &[u8]) -> Result<RgbImage, ImageError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(png_error)?;
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

    #[test]
    fn png_round_trip() {
        let mut image = RgbImage::new(20, 10);
        for (i, byte) in image.data.iter_mut().enumerate() {
            *byte = (i * 7 % 251) as u8;
        }
        assert_eq!(decode_png(&encode_png(&image).unwrap()).unwrap(), image);
    }

    #[test]
    fn a_png_that_cannot_be_read_is_named_a_png() {
        let error = decode_png(b"not a PNG at all").unwrap_err();
        assert!(error.to_string().starts_with("cannot decode the PNG: "), "{error}");
    }
}
