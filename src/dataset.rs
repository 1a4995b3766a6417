//! Recorded datasets in the Udacity format: `robot_log.csv` (`;`-separated, a header, one row per
//! frame: image path, steer, throttle, brake, speed, x, y, pitch, yaw, roll) and the JPEGs in `IMG/`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

/// One recorded frame.
#[derive(Debug, Clone)]
pub struct RecordedFrame {
    /// The image file.
    pub image: PathBuf,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Position x, metres.
    pub x_m: f64,
    /// Position y, metres.
    pub y_m: f64,
    /// Pitch, degrees as logged (0..360, positive nose down).
    pub pitch_deg: f64,
    /// Yaw, degrees counter-clockwise from +x.
    pub yaw_deg: f64,
    /// Roll, degrees as logged (0..360).
    pub roll_deg: f64,
}

impl RecordedFrame {
    /// Reads the frame's JPEG.
    pub fn jpeg(&self) -> anyhow::Result<Vec<u8>> {
        std::fs::read(&self.image).with_context(|| format!("cannot read {}", self.image.display()))
    }
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
    Ok(RecordedFrame {
        image: dir.join("IMG").join(file),
        speed_mps: number(4, "Speed")?,
        x_m: number(5, "X_Position")?,
        y_m: number(6, "Y_Position")?,
        pitch_deg: number(7, "Pitch")?,
        yaw_deg: number(8, "Yaw")?,
        roll_deg: number(9, "Roll")?,
    })
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
        assert_eq!(frames[0].yaw_deg, 56.82555);
        std::fs::write(dir.join("robot_log.csv"), "header\na.jpg;0;0;1;fast;1;2;3;4;5\n").unwrap();
        let error = format!("{:#}", read_log(&dir).unwrap_err());
        assert!(error.contains("line 2") && error.contains("Speed"), "{error}");
        std::fs::remove_dir_all(dir).unwrap();
    }
}
