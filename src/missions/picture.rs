//! The picture of a finished mission, for a person to read at a glance: the final map over the
//! ground truth at [`PX_PER_CELL`] pixels per cell, north up, the path driven, home, the samples
//! (collected or missed) and a legend with the scores. `rover demo` and `rover eval --maps` save it.

use std::path::Path;

use anyhow::Context as _;
use rover_imaging::RgbImage;
use rover_imaging::shapes::{draw_line, draw_ring, fill_disc, fill_rect};
use rover_imaging::text::{draw_text, text_height_px, text_width_px};
use rover_msgs::map_grid::{CELLS, SIDE_CELLS, cell_xy};
use rover_sim::sim::Simulator;

use crate::missions::eval::RunResult;

/// Pixels along each side of a map cell.
pub const PX_PER_CELL: usize = 4;
/// The path keeps a position when it is this far from the last one kept, metres.
const PATH_STEP_M: f64 = 0.25;
/// Font pixel size of the legend, pixels.
const TEXT_SCALE: usize = 3;
/// Space around and between the legend's parts, pixels.
const MARGIN_PX: usize = 16;
/// Height of one legend line, pixels.
const LINE_PX: usize = text_height_px(TEXT_SCALE) + 9;
/// Side of a legend colour swatch, pixels.
const SWATCH_PX: usize = text_height_px(TEXT_SCALE) + 3;
/// Width of the path, pixels.
const PATH_WIDTH_PX: f64 = 2.0;
/// Radius of a sample mark, pixels.
const SAMPLE_RADIUS_PX: f64 = 7.0;
/// Radius of the home mark, pixels.
const HOME_RADIUS_PX: f64 = 9.0;
/// Width of the rings that mark home and the missed samples, pixels.
const RING_WIDTH_PX: f64 = 3.0;

const GROUND_MAPPED: [u8; 3] = [40, 110, 230];
const GROUND_NOT_MAPPED: [u8; 3] = [85, 85, 85];
const GROUND_MAPPED_AS_OBSTACLE: [u8; 3] = [190, 150, 110];
const WRONGLY_MAPPED_AS_GROUND: [u8; 3] = [230, 60, 200];
const OBSTACLE_MAPPED: [u8; 3] = [120, 30, 30];
const NOT_GROUND: [u8; 3] = [20, 20, 20];
const PATH: [u8; 3] = [255, 220, 0];
const HOME: [u8; 3] = [0, 230, 230];
const SAMPLE_COLLECTED: [u8; 3] = [60, 230, 60];
const SAMPLE_MISSED: [u8; 3] = [255, 110, 0];
const TEXT: [u8; 3] = [255, 255, 255];

/// The colours of the picture with what they mean, in the legend's order.
const KEY: [([u8; 3], &str); 9] = [
    (GROUND_MAPPED, "GROUND MAPPED"),
    (GROUND_NOT_MAPPED, "GROUND NOT SEEN"),
    (GROUND_MAPPED_AS_OBSTACLE, "GROUND MAPPED AS OBSTACLE"),
    (WRONGLY_MAPPED_AS_GROUND, "WRONGLY MAPPED AS GROUND"),
    (OBSTACLE_MAPPED, "OBSTACLE MAPPED"),
    (PATH, "PATH DRIVEN"),
    (HOME, "HOME"),
    (SAMPLE_COLLECTED, "SAMPLE COLLECTED"),
    (SAMPLE_MISSED, "SAMPLE MISSED"),
];

/// The positions a rover drove through, kept every [`PATH_STEP_M`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DrivenPath {
    points_m: Vec<(f64, f64)>,
}

impl DrivenPath {
    /// Notes that the rover is at (`x_m`, `y_m`).
    pub fn record(&mut self, x_m: f64, y_m: f64) {
        let moved = self.points_m.last().is_none_or(|&(x, y)| (x - x_m).hypot(y - y_m) >= PATH_STEP_M);
        if moved {
            self.points_m.push((x_m, y_m));
        }
    }

    /// The positions kept, world metres, in order.
    pub fn points_m(&self) -> &[(f64, f64)] {
        &self.points_m
    }
}

/// A sample of the world and whether the rover collected it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleMark {
    /// x, world metres.
    pub x_m: f64,
    /// y, world metres.
    pub y_m: f64,
    /// Whether the rover picked it up.
    pub collected: bool,
}

/// Every sample of the simulated world, collected unless it still lies on the ground.
pub fn sample_marks(simulator: &Simulator) -> Vec<SampleMark> {
    let on_ground = simulator.samples();
    let marks = simulator.world().samples.iter();
    marks.map(|s| SampleMark { x_m: s.x_m, y_m: s.y_m, collected: !on_ground.contains(s) }).collect()
}

/// What the picture of a mission shows, gathered while it runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MissionMap {
    /// The final map as `nav_msgs/OccupancyGrid` data (0 ground, 100 obstacle, -1 unknown); empty
    /// if none arrived.
    pub occupancy: Vec<i8>,
    /// The true world: whether each cell is ground.
    pub ground_truth: Vec<bool>,
    /// The path driven.
    pub path: DrivenPath,
    /// The start, world metres.
    pub home_m: (f64, f64),
    /// The world's samples.
    pub samples: Vec<SampleMark>,
}

/// Draws the picture of `mission`, whose scores are `result`: the map on the left, the legend on
/// the right.
pub fn draw_mission(mission: &MissionMap, result: &RunResult) -> RgbImage {
    let lines = legend_lines(result);
    let map_px = SIDE_CELLS * PX_PER_CELL;
    let mut image = RgbImage::new(map_px + legend_width_px(&lines), map_px);
    draw_cells(&mut image, mission);
    draw_path(&mut image, mission.path.points_m());
    draw_ring(&mut image, pixel_of(mission.home_m), HOME_RADIUS_PX, RING_WIDTH_PX, HOME);
    draw_samples(&mut image, &mission.samples);
    draw_legend(&mut image, map_px + MARGIN_PX, &lines);
    image
}

/// Writes the picture of `mission`, whose scores are `result`, as the PNG file `path`.
pub fn write_mission_png(path: &Path, mission: &MissionMap, result: &RunResult) -> anyhow::Result<()> {
    let png = rover_imaging::encode_png(&draw_mission(mission, result))?;
    std::fs::write(path, png).with_context(|| format!("cannot write {}", path.display()))
}

/// The score lines of the legend.
fn legend_lines(result: &RunResult) -> Vec<String> {
    let verdict = if result.complete() { "MISSION COMPLETE" } else { "MISSION NOT COMPLETE" };
    vec![
        format!("SEED {}", result.seed),
        format!("MAPPED {:.1} %", result.mapped_pct),
        format!("FIDELITY {:.1} %", result.fidelity_pct),
        format!("SAMPLES COLLECTED {} OF {}", result.collected, result.samples),
        format!("TIME {:.0} S", result.sim_seconds),
        format!("HOME {:.1} M AWAY", result.home_distance_m),
        format!("DRIVEN {:.0} M", result.distance_m),
        verdict.to_string(),
    ]
}

/// Width of the legend beside the map, pixels: its widest line and the margins.
fn legend_width_px(lines: &[String]) -> usize {
    let scores = lines.iter().map(|line| text_width_px(line, TEXT_SCALE));
    let key = KEY.iter().map(|(_, meaning)| SWATCH_PX + MARGIN_PX / 2 + text_width_px(meaning, TEXT_SCALE));
    scores.chain(key).max().unwrap_or(0) + 2 * MARGIN_PX
}

/// The pixel centre of the world point `point_m`, north up.
fn pixel_of(point_m: (f64, f64)) -> (f64, f64) {
    let scale = PX_PER_CELL as f64;
    (point_m.0 * scale, (SIDE_CELLS as f64 - point_m.1) * scale)
}

/// The colour of a map cell holding `occupancy` where the ground truth says `ground`: true ground
/// is mapped (as ground) or not, as the mapped % counts it, and when not, mapped as an obstacle or
/// never seen; elsewhere ground on the map is an error, as the fidelity % counts it, and obstacles
/// are right.
fn cell_colour(occupancy: Option<i8>, ground: bool) -> [u8; 3] {
    let mapped_as_ground = occupancy == Some(0);
    let mapped_as_obstacle = occupancy.is_some_and(|value| value > 0);
    match (ground, mapped_as_ground) {
        (true, true) => GROUND_MAPPED,
        (true, false) if mapped_as_obstacle => GROUND_MAPPED_AS_OBSTACLE,
        (true, false) => GROUND_NOT_MAPPED,
        (false, true) => WRONGLY_MAPPED_AS_GROUND,
        (false, false) if mapped_as_obstacle => OBSTACLE_MAPPED,
        (false, false) => NOT_GROUND,
    }
}

fn draw_cells(image: &mut RgbImage, mission: &MissionMap) {
    for cell in 0..CELLS {
        let ground = mission.ground_truth.get(cell).copied().unwrap_or(false);
        let rgb = cell_colour(mission.occupancy.get(cell).copied(), ground);
        let (x, y) = cell_xy(cell);
        fill_rect(image, x * PX_PER_CELL, (SIDE_CELLS - 1 - y) * PX_PER_CELL, PX_PER_CELL, PX_PER_CELL, rgb);
    }
}

fn draw_path(image: &mut RgbImage, points_m: &[(f64, f64)]) {
    for pair in points_m.windows(2) {
        draw_line(image, pixel_of(pair[0]), pixel_of(pair[1]), PATH_WIDTH_PX, PATH);
    }
}

/// Collected samples as filled discs, missed ones as rings.
fn draw_samples(image: &mut RgbImage, samples: &[SampleMark]) {
    for sample in samples {
        let centre = pixel_of((sample.x_m, sample.y_m));
        if sample.collected {
            fill_disc(image, centre, SAMPLE_RADIUS_PX, SAMPLE_COLLECTED);
        } else {
            draw_ring(image, centre, SAMPLE_RADIUS_PX, RING_WIDTH_PX, SAMPLE_MISSED);
        }
    }
}

/// The score lines, then the colour key, from column `left`.
fn draw_legend(image: &mut RgbImage, left: usize, lines: &[String]) {
    let mut top = MARGIN_PX;
    for line in lines {
        draw_text(image, left, top, line, TEXT_SCALE, TEXT);
        top += LINE_PX;
    }
    top += LINE_PX;
    for (rgb, meaning) in KEY {
        fill_rect(image, left, top, SWATCH_PX, SWATCH_PX, rgb);
        draw_text(image, left + SWATCH_PX + MARGIN_PX / 2, top + 2, meaning, TEXT_SCALE, TEXT);
        top += LINE_PX;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mission() -> MissionMap {
        let mut path = DrivenPath::default();
        for step in 0..=40 {
            path.record(100.0 + step as f64 * 0.5, 100.0);
        }
        let mut occupancy = vec![-1; CELLS];
        occupancy[rover_msgs::map_grid::cell_at(10, 10)] = 0;
        let samples = vec![
            SampleMark { x_m: 50.0, y_m: 50.0, collected: true },
            SampleMark { x_m: 150.0, y_m: 50.0, collected: false },
        ];
        MissionMap { occupancy, ground_truth: vec![true; CELLS], path, home_m: (100.0, 100.0), samples }
    }

    #[test]
    fn the_path_keeps_a_position_every_quarter_metre() {
        let mut path = DrivenPath::default();
        for x_m in [0.0, 0.1, 0.2, 0.3, 0.6] {
            path.record(x_m, 0.0);
        }
        assert_eq!(path.points_m(), &[(0.0, 0.0), (0.3, 0.0), (0.6, 0.0)]);
    }

    #[test]
    fn draws_the_map_at_four_pixels_a_cell_and_the_legend_beside_it() {
        let image = draw_mission(&mission(), &RunResult::example());
        assert_eq!(image.height, 800);
        assert!(image.width > 800 + text_width_px("GROUND MAPPED AS OBSTACLE", TEXT_SCALE), "{}", image.width);
        let (x, y) = (10 * PX_PER_CELL + 1, (SIDE_CELLS - 11) * PX_PER_CELL + 1);
        assert_eq!(image.pixel(x, y), GROUND_MAPPED, "cell (10, 10), north up");
        assert_eq!(image.pixel(0, 0), GROUND_NOT_MAPPED);
        let legend = |rgb| (800..image.width).any(|x| (0..image.height).any(|y| image.pixel(x, y) == rgb));
        assert!(legend(TEXT) && KEY.iter().all(|&(rgb, _)| legend(rgb)), "text and every colour in the legend");
    }

    #[test]
    fn draws_the_path_home_and_the_samples_where_they_are() {
        let image = draw_mission(&mission(), &RunResult::example());
        assert_eq!(image.pixel(440, 400), PATH, "the path from x = 100 m to 120 m along y = 100 m");
        assert_eq!(image.pixel(400 + HOME_RADIUS_PX as usize, 400), HOME, "the home ring");
        assert_eq!(image.pixel(200, 600), SAMPLE_COLLECTED, "a collected sample is a disc");
        assert_eq!(image.pixel(600 + SAMPLE_RADIUS_PX as usize, 600), SAMPLE_MISSED, "a missed one a ring");
        assert_eq!(image.pixel(600, 600), GROUND_NOT_MAPPED, "with the map inside");
    }

    #[test]
    fn each_cell_is_coloured_as_the_scores_count_it() {
        assert_eq!(cell_colour(Some(0), true), GROUND_MAPPED);
        assert_eq!(cell_colour(Some(100), true), GROUND_MAPPED_AS_OBSTACLE);
        assert_eq!(cell_colour(Some(-1), true), GROUND_NOT_MAPPED);
        assert_eq!(cell_colour(Some(0), false), WRONGLY_MAPPED_AS_GROUND);
        assert_eq!(cell_colour(Some(100), false), OBSTACLE_MAPPED);
        assert_eq!(cell_colour(None, false), NOT_GROUND);
    }

    #[test]
    fn the_legend_gives_the_scores_in_words() {
        let lines = legend_lines(&RunResult::example());
        assert_eq!(
            lines[1..6],
            ["MAPPED 91.5 %", "FIDELITY 88.0 %", "SAMPLES COLLECTED 5 OF 6", "TIME 725 S", "HOME 1.2 M AWAY"]
        );
        assert_eq!(lines.last().map(String::as_str), Some("MISSION NOT COMPLETE"));
    }
}
