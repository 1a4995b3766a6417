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

/// The image of an rgb8 `Image` message, or why it is not one.
pub fn rgb_image_from_message(message: Image) -> Result<RgbImage, String> {
    let (width, height) = (message.width as usize, message.height as usize);
    if message.encoding != "rgb8" {
        return Err(format!("encoding {:?}, expected \"rgb8\"", message.encoding));
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
        let short = Image { data: vec![0; 5], ..message };
        assert!(rgb_image_from_message(short).unwrap_err().contains("5 bytes"));
    }
}
