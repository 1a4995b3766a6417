//! The rendered camera against the real one: the students' calibration points on the 1 m grid,
//! and the samples and the usual colour thresholds. (Floor, walls and sky are compared with the
//! 283 real frames themselves by `rover sim-check`, in `tests/sim_check.rs`.)

use rover_imaging::RgbImage;
use rover_sim::camera::{BodyPose, CameraModel};
use rover_sim::render::{RenderOptions, Renderer, Surface};
use rover_sim::world::{Sample, StartPose, WORLD_SIZE, World};

fn open_floor() -> World {
    World::open(vec![true; WORLD_SIZE * WORLD_SIZE], StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 })
}

fn darkness(image: &RgbImage, u: usize, v: usize) -> u32 {
    let [r, g, b] = image.pixel(u, v);
    765 - (r as u32 + g as u32 + b as u32)
}

/// Sub-pixel column of the grid line crossing row `v` near `expected`: the darkness-weighted centre
/// of the pixels around the darkest one within `expected` +- 8 px.
fn line_column(image: &RgbImage, v: usize, expected: f64) -> f64 {
    let expected = expected.round() as usize;
    let darkest = (expected.saturating_sub(8).max(6)..=(expected + 8).min(image.width - 7))
        .max_by_key(|&u| darkness(image, u, v))
        .unwrap();
    let background = darkness(image, darkest - 6, v).min(darkness(image, darkest + 6, v)) as f64;
    let weights: Vec<(f64, f64)> =
        (darkest - 3..=darkest + 3).map(|u| (u as f64, (darkness(image, u, v) as f64 - background).max(0.0))).collect();
    weights.iter().map(|(u, w)| u * w).sum::<f64>() / weights.iter().map(|(_, w)| w).sum::<f64>()
}

/// Follows a grid line from near (u_near, 140) to far (u_far, 96) between the horizontal lines and
/// returns where its least-squares fit crosses rows `near_row` and `far_row`.
fn diagonal_ends(image: &RgbImage, u_near: f64, u_far: f64, near_row: f64, far_row: f64) -> (f64, f64) {
    let expected = |v: f64| u_far + (u_near - u_far) * (v - 96.0) / 44.0;
    let points: Vec<(f64, f64)> =
        (101..=135).step_by(2).map(|v| (v as f64, line_column(image, v, expected(v as f64)))).collect();
    let n = points.len() as f64;
    let (mean_v, mean_u) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let slope = points.iter().map(|p| (p.0 - mean_v) * (p.1 - mean_u)).sum::<f64>()
        / points.iter().map(|p| (p.0 - mean_v).powi(2)).sum::<f64>();
    (mean_u + slope * (near_row - mean_v), mean_u + slope * (far_row - mean_v))
}

/// Sub-pixel row of the horizontal grid line near `expected`: the darkness-weighted centre of the
/// rows around the darkest one (columns 100..220).
fn line_row(image: &RgbImage, expected: usize) -> f64 {
    let row_darkness = |v: usize| (100..220).map(|u| darkness(image, u, v)).sum::<u32>() as f64;
    let darkest =
        (expected - 8..=(expected + 8).min(image.height - 7)).max_by_key(|&v| row_darkness(v) as u64).unwrap();
    let background = row_darkness(darkest - 6).min(row_darkness(darkest + 6));
    let weights: Vec<(f64, f64)> =
        (darkest - 3..=darkest + 3).map(|v| (v as f64, (row_darkness(v) - background).max(0.0))).collect();
    weights.iter().map(|(v, w)| v * w).sum::<f64>() / weights.iter().map(|(_, w)| w).sum::<f64>()
}

#[test]
fn the_calibration_points_fall_on_the_corners_of_the_grid_cell_ahead() {
    let world = open_floor();
    let camera = CameraModel::rover();
    let mut renderer = Renderer::new(&world, camera, RenderOptions { grid: true, ..RenderOptions::default() });
    // The fitted cell of unity-sim-spec 4.2: near edge 0.3992 m ahead of the camera, centred 0.007 m
    // to the right. Grid lines lie at k + 0.5 m.
    let pose = BodyPose { x_m: 100.5 - 0.3992 - camera.forward_m, y_m: 100.5 - 0.507, ..Default::default() };
    let mut image = RgbImage::default();
    renderer.render(&world, &[], &pose, &mut image);
    let (near_row, far_row) = (line_row(&image, 140), line_row(&image, 96));
    let (left_near, left_far) = diagonal_ends(&image, 14.0, 118.0, near_row, far_row);
    let (right_near, right_far) = diagonal_ends(&image, 301.0, 200.0, near_row, far_row);
    let corners = [
        ((14.0, 140.0), (left_near, near_row)),
        ((301.0, 140.0), (right_near, near_row)),
        ((200.0, 96.0), (right_far, far_row)),
        ((118.0, 96.0), (left_far, far_row)),
    ];
    for ((u, v), (found_u, found_v)) in corners {
        let error = (found_u - u).hypot(found_v - v);
        eprintln!("calibration point ({u}, {v}): rendered corner ({found_u:.1}, {found_v:.1}), {error:.2} px away");
        assert!(error <= 2.0, "calibration point ({u}, {v}) is {error:.2} px from the rendered corner");
    }
}

fn unity_world() -> World {
    let shared = |path: &str| {
        let path = format!("{}/../../shared/{path}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    };
    let (map, floor) = (shared("udacity/calibration_images/map_bw.png"), shared("udacity-world/floor_flat.png"));
    let (elevation, rocks) = (shared("udacity-world/elevation_cm.png"), shared("udacity-world/rocks.json"));
    let files = rover_sim::unity_world::UnityFiles {
        map_png: &map,
        floor_png: Some(&floor),
        elevation_png: Some(&elevation),
        rocks_json: Some(&rocks),
    };
    rover_sim::unity_world::unity_world(&files, 0).unwrap()
}

/// Poses looking at each sample from about 1.5 m, from floor cells around it.
fn poses_facing_samples(world: &World, samples: &[Sample]) -> Vec<BodyPose> {
    let mut poses = Vec::new();
    for sample in samples {
        for step in 0..16 {
            let angle = step as f64 * std::f64::consts::TAU / 16.0;
            let (x, y) = (sample.x_m - 1.8 * angle.cos(), sample.y_m - 1.8 * angle.sin());
            let clear =
                (-4..=4).all(|dy| (-4..=4).all(|dx| world.is_drivable(x + dx as f64 * 0.25, y + dy as f64 * 0.25)));
            if clear {
                poses.push(BodyPose { x_m: x, y_m: y, yaw_deg: angle.to_degrees(), ..Default::default() });
                break;
            }
        }
    }
    poses
}

#[derive(Default)]
struct Colours {
    pixels: Vec<[u8; 3]>,
}

impl Colours {
    fn median(&self) -> [u8; 3] {
        [0, 1, 2].map(|k| {
            let mut channel: Vec<u8> = self.pixels.iter().map(|p| p[k]).collect();
            channel.sort_unstable();
            channel[channel.len() / 2]
        })
    }

    fn mean(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| self.pixels.iter().map(|p| p[k] as f64).sum::<f64>() / self.pixels.len() as f64)
    }

    fn fraction(&self, test: impl Fn(&[u8; 3]) -> bool) -> f64 {
        self.pixels.iter().filter(|p| test(p)).count() as f64 / self.pixels.len() as f64
    }
}

fn navigable(p: &[u8; 3]) -> bool {
    p[0] > 160 && p[1] > 160 && p[2] > 160
}

fn rock(p: &[u8; 3]) -> bool {
    p[0] > 110 && p[1] > 110 && p[2] < 50
}

fn within(value: [f64; 3], low: [f64; 3], high: [f64; 3]) -> bool {
    (0..3).all(|k| low[k] <= value[k] && value[k] <= high[k])
}

#[test]
fn samples_look_like_unity_samples_and_the_usual_thresholds_work_but_not_perfectly() {
    let world = unity_world();
    let all_samples: Vec<Sample> = rover_sim::unity_world::UNITY_SAMPLE_CANDIDATES
        .iter()
        .map(|&(x_m, y_m)| Sample { x_m, y_m, radius_m: 0.09 })
        .collect();
    let mut poses = poses_facing_samples(&world, &all_samples);
    assert!(poses.len() >= 25, "found views of {} samples", poses.len());
    for yaw in (0..360).step_by(30) {
        poses.push(BodyPose {
            x_m: 99.67,
            y_m: 85.589,
            yaw_deg: yaw as f64,
            pitch_deg: 0.5,
            roll_deg: -0.8,
            ground_m: 0.0,
        });
    }
    let mut renderer =
        Renderer::new(&world, CameraModel::rover(), RenderOptions { record_hits: true, ..RenderOptions::default() });
    let mut by_surface: std::collections::HashMap<Surface, Colours> = Default::default();
    let mut image = RgbImage::default();
    for pose in &poses {
        renderer.render(&world, &all_samples, pose, &mut image);
        for (index, hit) in renderer.hits().iter().enumerate() {
            let pixel = image.pixel(index % image.width, index / image.width);
            by_surface.entry(hit.surface).or_default().pixels.push(pixel);
        }
    }
    let floor = &by_surface[&Surface::Floor];
    let walls = &by_surface[&Surface::Rock];
    let sky = &by_surface[&Surface::Sky];
    let samples = &by_surface[&Surface::Sample];
    let report = |name: &str, c: &Colours| {
        eprintln!("{name}: {} px, median {:?}, mean {:.0?}", c.pixels.len(), c.median(), c.mean())
    };
    report("floor", floor);
    report("walls", walls);
    report("sky", sky);
    report("samples", samples);
    assert!(within(samples.mean(), [140.0, 117.0, 0.0], [185.0, 157.0, 35.0]), "sample mean {:.0?}", samples.mean());
    assert!(samples.pixels.len() > 200, "samples are visible");

    let floor_navigable = floor.fraction(navigable);
    eprintln!(
        "RGB > 160: floor {floor_navigable:.3}, walls {:.4}, sky {:.4}; rock rule: samples {:.3}, floor {:.4}",
        walls.fraction(navigable),
        sky.fraction(navigable),
        samples.fraction(rock),
        floor.fraction(rock)
    );
    assert!(
        (0.75..0.995).contains(&floor_navigable),
        "floor read as navigable: {floor_navigable:.3} (sensible, not perfect: it darkens at the walls' foot)"
    );
    assert!(walls.fraction(navigable) < 0.01 && sky.fraction(navigable) < 0.01);
    assert!((0.6..0.98).contains(&samples.fraction(rock)), "samples read as rock: {:.3}", samples.fraction(rock));
    assert!(floor.fraction(rock) + walls.fraction(rock) < 0.002, "only samples read as rock");
}

#[test]
fn samples_lie_at_the_floors_height_so_one_on_a_wall_foot_is_half_in_the_slope() {
    let world = unity_world();
    let sample_pixels = |sample: Sample| {
        let pose = poses_facing_samples(&world, &[sample]).pop().expect("a free place facing the sample");
        let mut renderer = Renderer::new(
            &world,
            CameraModel::rover(),
            RenderOptions { record_hits: true, ..RenderOptions::default() },
        );
        let mut image = RgbImage::default();
        renderer.render(&world, &[sample], &pose, &mut image);
        renderer.hits().iter().filter(|hit| hit.surface == Surface::Sample).count()
    };
    let on_the_floor = Sample { x_m: 97.44, y_m: 74.65, radius_m: 0.09 };
    let on_a_wall_foot = Sample { x_m: 21.724, y_m: 102.178, radius_m: 0.09 };
    let (floor_ground_m, foot_ground_m) = (
        world.ground_height(on_the_floor.x_m, on_the_floor.y_m),
        world.ground_height(on_a_wall_foot.x_m, on_a_wall_foot.y_m),
    );
    assert!(floor_ground_m < 0.02 && (0.08..0.2).contains(&foot_ground_m), "{floor_ground_m} / {foot_ground_m} m");
    let (whole, half_hidden) = (sample_pixels(on_the_floor), sample_pixels(on_a_wall_foot));
    eprintln!("sample pixels from 1.8 m: on the floor {whole}, on the foot of a wall {half_hidden}");
    assert!(whole > 40, "a sample on the floor shows whole: {whole} pixels");
    assert!(half_hidden > 5 && half_hidden * 10 < whole * 8, "the slope hides part of it: {half_hidden} of {whole}");
}
