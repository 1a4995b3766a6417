//! Recorded datasets in the Udacity format: `robot_log.csv` (`;`-separated, a header, one row per
//! frame: image path, steer, throttle, brake, speed, x, y, pitch, yaw, roll) and the JPEGs in `IMG/`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_bridge::telemetry::SimTelemetry;
use rover_msgs::unity::ReportedState;

/// One recorded frame.
#[derive(Debug, Clone)]
pub struct RecordedFrame {
    /// The image file.
    pub image: PathBuf,
    /// The recorded controls and pose.
    pub state: ReportedState,
}

impl RecordedFrame {
    /// Reads the frame's JPEG.
    pub fn jpeg(&self) -> anyhow::Result<Vec<u8>> {
        std::fs::read(&self.image).with_context(|| format!("cannot read {}", self.image.display()))
    }

    /// The frame as the simulator would send it, with the image `jpeg`, no samples.
    pub fn sim_telemetry(&self, jpeg: Vec<u8>) -> SimTelemetry {
        SimTelemetry {
            state: self.state,
            near_sample: false,
            picking_up: false,
            sample_count: 0,
            samples: Vec::new(),
            image_jpeg: jpeg,
        }
    }

    /// When the frame was taken, nanoseconds since the epoch, from its image's name
    /// (`robocam_YYYY_MM_DD_hh_mm_ss_mmm.jpg`, read as UTC).
    pub fn time_ns(&self) -> anyhow::Result<u64> {
        let name = self.image.file_stem().and_then(|n| n.to_str()).unwrap_or_default();
        time_ns_of_image_name(name).with_context(|| {
            format!("cannot read the time of {}: expected robocam_YYYY_MM_DD_hh_mm_ss_mmm.jpg", self.image.display())
        })
    }
}

/// The time in an image name `robocam_YYYY_MM_DD_hh_mm_ss_mmm`, nanoseconds since the epoch (UTC).
fn time_ns_of_image_name(name: &str) -> Option<u64> {
    let numbers: Vec<u32> =
        name.strip_prefix("robocam_")?.split('_').map(|part| part.parse().ok()).collect::<Option<_>>()?;
    let [year, month, day, hour, minute, second, millisecond] = numbers[..] else { return None };
    let time = chrono::NaiveDate::from_ymd_opt(i32::try_from(year).ok()?, month, day)?.and_hms_milli_opt(
        hour,
        minute,
        second,
        Some(millisecond).filter(|&ms| ms < 1000)?,
    )?;
    u64::try_from(time.and_utc().timestamp_nanos_opt()?).ok()
}

/// Reads `robot_log.csv` of the dataset in `dir`; image paths are resolved to `dir/IMG/<file name>`.
pub fn read_log(dir: &Path) -> anyhow::Result<Vec<RecordedFrame>> {
    let log = dir.join("robot_log.csv");
    let text = std::fs::read_to_string(&log).with_context(|| format!("cannot read {}", log.display()))?;
    text.lines()
        .enumerate()
        .skip(1)
        .filter(|(_, line)| !line.trim().is_empty())
        .map(|(index, line)| parse_row(dir, line).with_context(|| format!("{} line {}", log.display(), index + 1)))
        .collect()
}

fn parse_row(dir: &Path, line: &str) -> anyhow::Result<RecordedFrame> {
    let cells: Vec<&str> = line.split(';').collect();
    anyhow::ensure!(cells.len() >= 10, "expected 10 ';'-separated columns, found {}", cells.len());
    let number = |i: usize, name: &str| -> anyhow::Result<f64> {
        cells[i]
            .trim()
            .replace(',', ".")
            .parse::<f64>()
            .with_context(|| format!("column {name} = {:?} is not a number", cells[i]))
    };
    let file =
        Path::new(cells[0].trim()).file_name().with_context(|| format!("no image file name in {:?}", cells[0]))?;
    let state = ReportedState {
        steering_angle_deg: number(1, "SteerAngle")?,
        throttle: number(2, "Throttle")?,
        brake: number(3, "Brake")?,
        speed_mps: number(4, "Speed")?,
        x_m: number(5, "X_Position")?,
        y_m: number(6, "Y_Position")?,
        pitch_deg: number(7, "Pitch")?,
        yaw_deg: number(8, "Yaw")?,
        roll_deg: number(9, "Roll")?,
    };
    Ok(RecordedFrame { image: dir.join("IMG").join(file), state })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_rows_and_names_bad_ones() {
        let dir = std::env::temp_dir().join(format!("rover-dataset-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("robot_log.csv"),
            "Path;SteerAngle;Throttle;Brake;Speed;X_Position;Y_Position;Pitch;Yaw;Roll\n../x/IMG/a.jpg;0;0;1;0;99.66999;85.58897;0.0002364085;56.82555;2.093137E-07\n",
        )
        .unwrap();
        let frames = read_log(&dir).unwrap();
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].image, dir.join("IMG/a.jpg"));
        assert_eq!(frames[0].state.yaw_deg, 56.82555);
        assert!(frames[0].time_ns().unwrap_err().to_string().contains("a.jpg"));
        std::fs::write(dir.join("robot_log.csv"), "header\na.jpg;0;0;1;fast;1;2;3;4;5\n").unwrap();
        let error = format!("{:#}", read_log(&dir).unwrap_err());
        assert!(error.contains("line 2") && error.contains("Speed"), "{error}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn image_names_give_the_frame_time_in_utc() {
        let ns = |name: &str| time_ns_of_image_name(name);
        assert_eq!(ns("robocam_1970_01_01_00_00_01_500"), Some(1_500_000_000));
        assert_eq!(ns("robocam_2017_05_02_11_16_21_421"), Some(1_493_723_781_421_000_000));
        assert_eq!(ns("robocam_2024_03_01_00_00_00_000"), Some(1_709_251_200_000_000_000));
        assert_eq!(ns("robocam_2017_13_02_11_16_21_421"), None);
        assert_eq!(ns("robocam_2017_05_02_11_16_21"), None);
        assert_eq!(ns("frame_0001"), None);
    }
}
