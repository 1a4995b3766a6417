//! RGB images as `sensor_msgs/Image` messages (encoding `rgb8`) and back.

use rover_msgs::sensor_msgs::Image;
use rover_msgs::std_msgs::Header;

use crate::RgbImage;

/// `image` as an rgb8 `Image` message with `header`.
pub fn rgb8_message(image: RgbImage, header: Header) -> Image {
    Image {
        header,
        height: image.height as u32,
        width: image.width as u32,
        encoding: "rgb8".to_string(),
        is_bigendian: 0,
        step: image.width as u32 * 3,
        data: image.data,
    }
}

/// The image of an rgb8 `Image` message, or why it is not one (another encoding, more than
/// [`crate::MAX_PNG_PIXELS`] pixels, or rows that do not match its size).
pub fn rgb_image_from_message(message: Image) -> Result<RgbImage, String> {
    let (width, height) = (message.width as usize, message.height as usize);
    if message.encoding != "rgb8" {
        return Err(format!("encoding {:?}, expected \"rgb8\"", message.encoding));
    }
    if u64::from(message.width) * u64::from(message.height) > crate::MAX_PNG_PIXELS {
        return Err(format!("{width}x{height} pixels, more than the {} accepted", crate::MAX_PNG_PIXELS));
    }
    if message.step as usize != width * 3 || message.data.len() != width * height * 3 {
        return Err(format!("{} bytes with step {} for {width}x{height} rgb8", message.data.len(), message.step));
    }
    Ok(RgbImage { width, height, data: message.data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_survives_the_round_trip_and_other_encodings_are_refused() {
        let image = RgbImage { width: 2, height: 1, data: vec![1, 2, 3, 4, 5, 6] };
        let message = rgb8_message(image.clone(), Header::default());
        assert_eq!((message.step, message.encoding.as_str()), (6, "rgb8"));
        assert_eq!(rgb_image_from_message(message.clone()), Ok(image));
        let bgr = Image { encoding: "bgr8".into(), ..message.clone() };
        assert!(rgb_image_from_message(bgr).unwrap_err().contains("bgr8"));
        let short = Image { data: vec![0; 5], ..message.clone() };
        assert!(rgb_image_from_message(short).unwrap_err().contains("5 bytes"));
        let huge = Image { width: u32::MAX, height: u32::MAX, step: u32::MAX, ..message };
        assert!(rgb_image_from_message(huge).unwrap_err().contains("more than"));
    }

    /// Fuzz target: an `Image` as a peer publishes it (any size, step, encoding and data) is taken
    /// or refused, never a panic, and what is taken encodes as the bridge's inset JPEG.
    mod fuzz {
        use proptest::prelude::*;

        use super::*;

        fn image() -> impl Strategy<Value = Image> {
            let sides = prop_oneof![0u32..40, any::<u32>()];
            let encoding = prop_oneof![Just("rgb8".to_string()), "\\PC{0,6}"];
            (sides.clone(), sides, prop_oneof![0u32..130, any::<u32>()], encoding, 0usize..5000).prop_map(
                |(width, height, step, encoding, bytes)| Image {
                    width,
                    height,
                    step,
                    encoding,
                    data: vec![7; bytes],
                    ..Image::default()
                },
            )
        }

        proptest! {
            #[test]
            fn fuzz_inset_image_messages(message in image()) {
                if let Ok(image) = rgb_image_from_message(message) {
                    prop_assert_eq!(image.data.len(), image.width * image.height * 3);
                    let _ = crate::encode_jpeg(&image, 75);
                }
            }
        }
    }
}
