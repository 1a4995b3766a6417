//! The 283 recorded frames of `../shared/udacity/test_dataset`: JPEG bytes and the logged pose.

use std::path::Path;

/// One recorded frame.
#[derive(Debug, Clone)]
pub struct RecordedFrame {
    pub jpeg: Vec<u8>,
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
    pub speed_mps: f64,
}

/// Reads every frame listed in `robot_log.csv`.
pub fn load(dataset: &Path) -> Vec<RecordedFrame> {
    let log = std::fs::read_to_string(dataset.join("robot_log.csv")).expect("read robot_log.csv");
    log.lines()
        .skip(1)
        .map(|line| {
            let cells: Vec<&str> = line.split(';').collect();
            let number = |i: usize| cells[i].parse::<f64>().unwrap_or_else(|_| panic!("bad number in {line}"));
            let file = Path::new(cells[0]).file_name().expect("image file name");
            RecordedFrame {
                jpeg: std::fs::read(dataset.join("IMG").join(file)).expect("read a recorded image"),
                speed_mps: number(4),
                x_m: number(5),
                y_m: number(6),
                pitch_deg: number(7),
                yaw_deg: number(8),
                roll_deg: number(9),
            }
        })
        .collect()
}
