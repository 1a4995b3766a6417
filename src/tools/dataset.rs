//! Recorded datasets in the Udacity format, read as the simulator wrote them on the recording
//! machine: `robot_log.csv` (one row per frame: image path, steer, throttle, brake, speed, x, y,
//! pitch, yaw, roll) and the JPEGs in `IMG/` beside it. The log may be `;`- or `,`-separated, with
//! or without its header line, with CRLF line ends; `Path` may hold a Windows, macOS or relative
//! path of another machine: the image is the file of that name in `IMG/`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_bridge::telemetry::SimTelemetry;
use rover_msgs::unity::ReportedState;

/// The log's file name inside a dataset folder.
pub const LOG_FILE: &str = "robot_log.csv";
/// Largest recording log read, bytes: a frame takes under 200 bytes, so some million frames.
const MAX_LOG_BYTES: u64 = 256 << 20;

/// The log's columns in the order the simulator writes them.
const COLUMNS: [&str; 10] =
    ["Path", "SteerAngle", "Throttle", "Brake", "Speed", "X_Position", "Y_Position", "Pitch", "Yaw", "Roll"];

/// One recorded frame.
#[derive(Debug, Clone)]
pub struct RecordedFrame {
    /// The image file.
    pub image: PathBuf,
    /// The recorded controls and pose, angles in [0, 360) as the simulator reports them.
    pub state: ReportedState,
}

impl RecordedFrame {
    /// Reads the frame's JPEG.
    pub fn jpeg(&self) -> anyhow::Result<Vec<u8>> {
        Ok(rover_files::read_at_most(&self.image, rover_imaging::MAX_IMAGE_FILE_BYTES)?)
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

/// A recording as read: its frames and what the reader made of the log.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The frames, in the log's order.
    pub frames: Vec<RecordedFrame>,
    /// How the log was read.
    pub report: ReadReport,
}

/// How a log was read, for the user: its form and the rows left out, with why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReadReport {
    /// The log file.
    pub log: PathBuf,
    /// The column separator found.
    pub separator: char,
    /// Whether the log starts with a header line.
    pub header: bool,
    /// Frames read.
    pub frames: usize,
    /// Rows left out, each with its line number and why.
    pub skipped: Vec<SkippedRow>,
}

/// A row of the log that gave no frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SkippedRow {
    /// Its line number, from 1.
    pub line: usize,
    /// Why it was left out.
    pub reason: String,
}

impl std::fmt::Display for ReadReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let header = if self.header { "with" } else { "without" };
        write!(
            f,
            "{}: {} frames ('{}'-separated, {header} a header line), {} rows skipped",
            self.log.display(),
            self.frames,
            self.separator,
            self.skipped.len()
        )?;
        for row in self.skipped.iter().take(5) {
            write!(f, "; line {}: {}", row.line, row.reason)?;
        }
        if self.skipped.len() > 5 {
            write!(f, "; ...")?;
        }
        Ok(())
    }
}

/// Reads a dataset: `path` is its folder (with `robot_log.csv` and `IMG/`) or the log itself.
/// Blank lines, a repeated header line and rows whose image is not in `IMG/` are skipped and
/// reported; any other row that is not a frame is an error naming its line.
pub fn read_log(path: &Path) -> anyhow::Result<Recording> {
    let (log, dir) = if path.is_dir() {
        (path.join(LOG_FILE), path.to_path_buf())
    } else {
        (path.to_path_buf(), path.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf))
    };
    let bytes = rover_files::read_at_most(&log, MAX_LOG_BYTES).with_context(|| {
        format!("cannot read the recording: expected a dataset folder with {LOG_FILE} and IMG/, or the log itself")
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let recording = parse_log(&text, &dir.join("IMG"), &log)?;
    tracing::info!("{}", recording.report);
    Ok(recording)
}

/// Parses the text of a log whose images are in `images`; `log` names it in messages.
fn parse_log(text: &str, images: &Path, log: &Path) -> anyhow::Result<Recording> {
    let mut lines = text.trim_start_matches('\u{feff}').lines().enumerate().map(|(i, line)| (i + 1, line.trim()));
    let mut skipped = Vec::new();
    let Some((first_number, first)) = lines.by_ref().find(|(number, line)| {
        let blank = line.is_empty();
        if blank {
            skipped.push(SkippedRow { line: *number, reason: "blank".into() });
        }
        !blank
    }) else {
        anyhow::bail!("{} has no rows", log.display());
    };
    let separator = separator_of(first).with_context(|| format!("{} line {first_number}", log.display()))?;
    let header = is_header(first, separator);
    let columns = if header {
        column_order(first, separator).with_context(|| format!("{} line {first_number}", log.display()))?
    } else {
        std::array::from_fn(|i| i)
    };
    let rows = (!header).then_some((first_number, first)).into_iter().chain(lines);
    let mut frames = Vec::new();
    for (number, line) in rows {
        if line.is_empty() || is_repeated_header(line, separator) {
            let reason = if line.is_empty() { "blank" } else { "a repeated header line" };
            skipped.push(SkippedRow { line: number, reason: reason.into() });
            continue;
        }
        let frame =
            parse_row(line, separator, &columns, images).with_context(|| format!("{} line {number}", log.display()))?;
        if frame.image.is_file() {
            frames.push(frame);
        } else {
            skipped.push(SkippedRow { line: number, reason: format!("no image {}", frame.image.display()) });
        }
    }
    skipped.sort_by_key(|row| row.line);
    let report = ReadReport { log: log.to_path_buf(), separator, header, frames: frames.len(), skipped };
    Ok(Recording { frames, report })
}

/// The separator of a log whose first row is `line`: `;` (the simulator's), else `,` (early
/// builds), whichever splits it into at least the ten columns.
fn separator_of(line: &str) -> anyhow::Result<char> {
    [';', ','].into_iter().find(|&s| line.split(s).count() >= COLUMNS.len()).with_context(|| {
        format!(
            "expected {} columns separated by ';' or ',' ({}), found {:?}",
            COLUMNS.len(),
            COLUMNS.join(";"),
            truncated(line)
        )
    })
}

/// True if no column after the first holds a number: a header line.
fn is_header(line: &str, separator: char) -> bool {
    line.split(separator).skip(1).all(|cell| number_of(cell).is_none())
}

/// True if `line` is a header naming every column: logs joined together repeat it.
fn is_repeated_header(line: &str, separator: char) -> bool {
    is_header(line, separator) && column_order(line, separator).is_ok()
}

/// For each of [`COLUMNS`], its index in the header `line`.
fn column_order(line: &str, separator: char) -> anyhow::Result<[usize; 10]> {
    let names: Vec<String> = line.split(separator).map(|name| name.trim().to_ascii_lowercase()).collect();
    let mut order = [0; 10];
    for (slot, wanted) in order.iter_mut().zip(COLUMNS) {
        *slot = names.iter().position(|name| *name == wanted.to_ascii_lowercase()).with_context(|| {
            format!("the header has no column {wanted}: expected {}, found {:?}", COLUMNS.join(";"), truncated(line))
        })?;
    }
    Ok(order)
}

/// A cell as a number: decimal point or comma, surrounding blanks allowed.
fn number_of(cell: &str) -> Option<f64> {
    cell.trim().replace(',', ".").parse::<f64>().ok()
}

/// The row `line` as a frame, its columns at `columns` (in the order of [`COLUMNS`]).
fn parse_row(line: &str, separator: char, columns: &[usize; 10], images: &Path) -> anyhow::Result<RecordedFrame> {
    let cells: Vec<&str> = line.split(separator).collect();
    let needed = columns.iter().max().map_or(0, |&last| last + 1);
    anyhow::ensure!(
        cells.len() >= needed,
        "expected {needed} '{separator}'-separated columns, found {}: {:?}",
        cells.len(),
        truncated(line)
    );
    let number = |k: usize| -> anyhow::Result<f64> {
        let cell = cells[columns[k]];
        number_of(cell)
            .filter(|v| v.is_finite())
            .with_context(|| format!("column {} = {:?} is not a finite number", COLUMNS[k], cell.trim()))
    };
    let angle = |k: usize| number(k).map(|deg| deg.rem_euclid(360.0));
    let path = cells[columns[0]].trim();
    let file = file_name_of(path).with_context(|| format!("column Path = {path:?} names no image file"))?;
    let state = ReportedState {
        steering_angle_deg: number(1)?,
        throttle: number(2)?,
        brake: number(3)?,
        speed_mps: number(4)?,
        x_m: number(5)?,
        y_m: number(6)?,
        pitch_deg: angle(7)?,
        yaw_deg: angle(8)?,
        roll_deg: angle(9)?,
    };
    Ok(RecordedFrame { image: images.join(file), state })
}

/// The last component of a path written on any system (`/` or `\` between folders).
fn file_name_of(path: &str) -> Option<&str> {
    path.rsplit(['/', '\\']).next().filter(|name| !name.is_empty() && *name != "." && *name != "..")
}

/// The start of a long line, for messages.
fn truncated(line: &str) -> String {
    line.chars().take(120).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "Path;SteerAngle;Throttle;Brake;Speed;X_Position;Y_Position;Pitch;Yaw;Roll";

    /// A dataset folder with `log` as its log and images `a.jpg` and `b.jpg`.
    struct Dataset(PathBuf);

    impl Dataset {
        fn new(name: &str, log: &str) -> Self {
            let dir = std::env::temp_dir().join(format!("rover-dataset-{name}-{}", std::process::id()));
            std::fs::create_dir_all(dir.join("IMG")).unwrap();
            for image in ["a.jpg", "b.jpg"] {
                std::fs::write(dir.join("IMG").join(image), b"jpeg").unwrap();
            }
            std::fs::write(dir.join(LOG_FILE), log).unwrap();
            Dataset(dir)
        }

        fn read(&self) -> anyhow::Result<Recording> {
            read_log(&self.0)
        }
    }

    impl Drop for Dataset {
        fn drop(&mut self) {
            std::fs::remove_dir_all(&self.0).ok();
        }
    }

    #[test]
    fn reads_the_simulators_own_log() {
        let log = format!("{HEADER}\n../x/IMG/a.jpg;0;0;1;0;99.66999;85.58897;0.0002364085;56.82555;2.093137E-07\n");
        let dataset = Dataset::new("plain", &log);
        let recording = dataset.read().unwrap();
        assert_eq!(recording.frames.len(), 1);
        assert_eq!(recording.frames[0].image, dataset.0.join("IMG/a.jpg"));
        assert_eq!(recording.frames[0].state.yaw_deg, 56.82555);
        assert_eq!((recording.report.separator, recording.report.header), (';', true));
        assert!(recording.frames[0].time_ns().unwrap_err().to_string().contains("a.jpg"));
    }

    #[test]
    fn reads_windows_and_macos_paths_crlf_and_wrapped_angles() {
        let log = format!(
            "{HEADER}\r\nC:\\Users\\someone\\Desktop\\data\\IMG\\a.jpg;0;0;1;0;1;2;359.5;30;-2\r\n\
             /Users/someone/Desktop/data/IMG/b.jpg;0;0;1;0;3;4;361;30;2\r\n"
        );
        let dataset = Dataset::new("paths", &log);
        let frames = dataset.read().unwrap().frames;
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].image, dataset.0.join("IMG/a.jpg"));
        assert_eq!(frames[1].image, dataset.0.join("IMG/b.jpg"));
        assert_eq!((frames[0].state.pitch_deg, frames[0].state.roll_deg), (359.5, 358.0));
        assert!((frames[1].state.pitch_deg - 1.0).abs() < 1e-9);
    }

    #[test]
    fn reads_commas_and_logs_without_a_header() {
        let commas =
            Dataset::new("commas", "IMG/a.jpg,0,0.5,0,1.5,10.25,20.5,0,90,0\nIMG/b.jpg,0,0,0,0,11,21,0,91,0\n");
        let recording = commas.read().unwrap();
        assert_eq!((recording.report.separator, recording.report.header), (',', false));
        assert_eq!(recording.frames.len(), 2, "the first row is a frame");
        assert_eq!((recording.frames[0].state.throttle, recording.frames[0].state.x_m), (0.5, 10.25));
        let decimal_commas = Dataset::new("decimal-commas", "a.jpg;0;0;0;0;10,5;20,25;0;90;0\n");
        assert_eq!(decimal_commas.read().unwrap().frames[0].state.y_m, 20.25);
    }

    #[test]
    fn a_header_in_another_order_names_the_columns() {
        let log =
            "x_position;y_position;path;steerangle;throttle;brake;speed;pitch;yaw;roll\n5;6;b.jpg;1;2;3;4;7;8;9\n";
        let frame = &Dataset::new("order", log).read().unwrap().frames[0];
        assert_eq!((frame.state.x_m, frame.state.y_m, frame.state.roll_deg), (5.0, 6.0, 9.0));
        assert!(frame.image.ends_with("IMG/b.jpg"));
    }

    #[test]
    fn skipped_rows_are_reported_with_their_lines() {
        let log = format!("{HEADER}\na.jpg;0;0;0;0;1;2;0;0;0\n\n{HEADER}\nmissing.jpg;0;0;0;0;1;2;0;0;0\n");
        let recording = Dataset::new("skipped", &log).read().unwrap();
        assert_eq!(recording.frames.len(), 1);
        let lines: Vec<usize> = recording.report.skipped.iter().map(|row| row.line).collect();
        assert_eq!(lines, [3, 4, 5]);
        let text = recording.report.to_string();
        assert!(
            text.contains("1 frames") && text.contains("line 5: no image") && text.contains("missing.jpg"),
            "{text}"
        );
    }

    #[test]
    fn a_bad_row_is_an_error_naming_its_line() {
        let error = |log: &str| format!("{:#}", Dataset::new("bad", log).read().unwrap_err());
        let text = error(&format!("{HEADER}\na.jpg;0;0;1;0;1;2;0;0;0\na.jpg;0;0;1;fast;1;2;3;4;5\n"));
        assert!(text.contains("line 3") && text.contains("Speed") && text.contains("fast"), "{text}");
        let text = error(&format!("{HEADER}\na.jpg;0;0;1;0;1;2;0;0\n"));
        assert!(text.contains("line 2") && text.contains("found 9"), "{text}");
        let text = error(&format!("{HEADER}\na.jpg;0;0;1;0;NaN;2;0;0;0\n"));
        assert!(text.contains("line 2") && text.contains("X_Position"), "{text}");
        let text = error(&format!("{HEADER}\nC:\\data\\IMG\\;0;0;1;0;1;2;0;0;0\n"));
        assert!(text.contains("line 2") && text.contains("names no image"), "{text}");
        let text = error("one column only\n");
        assert!(text.contains("line 1") && text.contains("separated by ';' or ','"), "{text}");
        let text = error("Path;Steer;Throttle;Brake;Speed;X_Position;Y_Position;Pitch;Yaw;Roll\n");
        assert!(text.contains("no column SteerAngle"), "{text}");
    }

    #[test]
    fn the_log_itself_can_be_named() {
        let dataset = Dataset::new("file", &format!("{HEADER}\nIMG/a.jpg;0;0;0;0;1;2;0;0;0\n"));
        assert_eq!(read_log(&dataset.0.join(LOG_FILE)).unwrap().frames.len(), 1);
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

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_text;

        use super::*;

        fn logs() -> Vec<String> {
            vec![
                format!("{HEADER}\r\nC:\\data\\IMG\\a.jpg;0;0,5;0;1;99.66999;85.58897;359.9;56.82;0.01\r\n"),
                "IMG/a.jpg,0,0.5,0,1,10.25,20.5,0,90,0\n/Users/x/IMG/b.jpg,0,0,0,0,11,21,0,91,0\n".into(),
            ]
        }

        proptest! {
            #[test]
            fn fuzz_dataset_mutated_logs(text in mutated_text(logs())) {
                let images = Path::new("/nonexistent/IMG");
                if let Ok(recording) = parse_log(&text, images, Path::new("robot_log.csv")) {
                    prop_assert!(recording.frames.is_empty(), "no image exists, so every row is skipped");
                    prop_assert!(recording.report.skipped.len() <= text.lines().count());
                }
            }
        }
    }
}
