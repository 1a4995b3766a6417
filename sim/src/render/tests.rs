use super::*;
use crate::world::{StartPose, WORLD_SIZE};

#[test]
fn a_level_camera_on_open_floor_sees_floor_below_the_horizon_and_sky_above() {
    let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
    let world = World::open(floor, StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 });
    let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
    let mut renderer = Renderer::new(&world, CameraModel::rover(), options);
    let mut image = RgbImage::default();
    renderer.render(&world, &[], &BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() }, &mut image);
    let surface = |u: usize, v: usize| renderer.hits()[v * 320 + u].surface;
    assert_eq!(surface(160, 150), Surface::Floor);
    assert_eq!(surface(160, 10), Surface::Sky);
    assert_eq!(surface(160, 60), Surface::Rock, "the world's edge is a wall 100 m away, 38.7 m high");
    let [r, g, b] = image.pixel(160, 150);
    assert!(r > 200 && g > 190 && b > 180, "bright floor: {:?}", [r, g, b]);
}

/// An open world with an overhanging boulder and a cluster of pieces ahead of (100, 100).
fn world_with_boulders() -> World {
    use crate::boulder::{Boulder, BoulderKind, BoulderSpec, Cap};
    use crate::random::SplitMix64;
    let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
    let cap = Cap { offset_m: [-1.0, 0.5], radius_m: 2.5, underside_m: 1.6, thickness_m: 2.0 };
    let specs = [
        BoulderSpec { x_m: 106.0, y_m: 100.5, footprint_radius_m: 1.2, kind: BoulderKind::Overhang(cap) },
        BoulderSpec { x_m: 103.0, y_m: 97.5, footprint_radius_m: 0.8, kind: BoulderKind::Cluster },
    ];
    let boulders = specs.iter().map(|spec| Boulder::new(spec, &mut SplitMix64::new(5))).collect();
    let start = crate::world::StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 };
    let plan = crate::world::WorldPlan {
        ground_truth: floor.clone(),
        floor,
        boulders,
        surveyed_rocks: vec![],
        samples: vec![],
        start,
        ground: crate::world::Ground::Generated { salt: 0 },
    };
    World::build(plan)
}

/// Renders `world` from `pose` and casts every pixel's ray at every boulder piece: how many
/// pixels show a boulder, and at how many the drawing and the ray disagree about it.
fn boulder_pixels_and_disagreements(world: &World, pose: &BodyPose) -> (usize, usize) {
    let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
    let camera = CameraModel::rover();
    let mut renderer = Renderer::new(world, camera, options);
    renderer.render(world, &[], pose, &mut RgbImage::default());
    let view = LevelView::new(&camera, camera.position(pose), pose.yaw_deg);
    let faces: Vec<_> = world
        .boulders()
        .iter()
        .flat_map(|b| &b.pieces)
        .map(|p| objects::FacesFromCamera::new(p, &view.camera))
        .collect();
    let (mut boulder_pixels, mut disagreements) = (0, 0);
    let mut across = Vec::new();
    for (index, hit) in renderer.hits().iter().enumerate() {
        let (u, v) = (index % 320 + MARGIN_PX, index / 320 + MARGIN_PX);
        let [dx, dy] = view.column_direction(u);
        let nearest = faces
            .iter()
            .filter_map(|f| {
                f.across_column(dx, dy, &mut across);
                f.entry(&across, view.row_rise(v) as f32).map(|(t, _)| t)
            })
            .fold(f32::INFINITY, f32::min);
        let agrees = if hit.surface == Surface::Boulder {
            boulder_pixels += 1;
            (hit.depth_m - nearest).abs() < 1e-3 * nearest
        } else {
            nearest >= hit.depth_m * (1.0 - 1e-3)
        };
        disagreements += !agrees as usize;
    }
    (boulder_pixels, disagreements)
}

#[test]
fn boulders_drawn_face_by_face_are_where_their_rays_meet_them() {
    let world = world_with_boulders();
    let pose = BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() };
    let (boulder_pixels, disagreements) = boulder_pixels_and_disagreements(&world, &pose);
    assert!(boulder_pixels > 2000, "{boulder_pixels} boulder pixels");
    assert!(
        disagreements * 100 < boulder_pixels,
        "{disagreements} of {boulder_pixels} pixels disagree at the outlines"
    );
}

#[test]
fn a_boulder_reaching_behind_the_camera_is_drawn_where_its_rays_meet_it() {
    let world = world_with_boulders();
    let pose = BodyPose { x_m: 102.6, y_m: 98.9, yaw_deg: -20.0, ..Default::default() };
    let camera = CameraModel::rover();
    let view = LevelView::new(&camera, camera.position(&pose), pose.yaw_deg);
    let straddles = |piece: &crate::boulder::ConvexPiece| {
        let depths = piece.vertices.iter().map(|p| view.depth(p));
        let (nearest, farthest) = depths.fold((f64::MAX, f64::MIN), |(lo, hi), d| (lo.min(d), hi.max(d)));
        nearest < view::NEAR_M && farthest > 1.0
    };
    assert!(world.boulders().iter().flat_map(|b| &b.pieces).any(straddles), "a piece reaches behind the camera");
    let (boulder_pixels, disagreements) = boulder_pixels_and_disagreements(&world, &pose);
    assert!(boulder_pixels > 5000, "{boulder_pixels} boulder pixels");
    assert!(
        disagreements * 100 < boulder_pixels,
        "{disagreements} of {boulder_pixels} pixels disagree at the outlines"
    );
}

/// An open world with a surveyed rock ahead of (100, 100): a dome of 0.25 m columns, standing
/// on the floor in its middle and raised 0.6 m off it under its rim.
fn world_with_a_surveyed_rock() -> World {
    let (cols, cell_m, origin) = (14, 0.25, [101.75, 98.25]);
    let grid = |value: &dyn Fn(f64) -> Option<f64>| {
        let rows: Vec<String> = (0..cols)
            .map(|r| {
                let cells: Vec<String> = (0..cols)
                    .map(|c| {
                        let radius =
                            ((c as f64 + 0.5 - cols as f64 / 2.0).hypot(r as f64 + 0.5 - cols as f64 / 2.0)) * cell_m;
                        value(radius).map_or("null".into(), |v| format!("{v:.2}"))
                    })
                    .collect();
                format!("[{}]", cells.join(","))
            })
            .collect();
        format!("[{}]", rows.join(","))
    };
    let top = grid(&|r| (r < 1.7).then_some(1.6 - r * 0.5));
    let bottom = grid(&|r| (r < 1.7).then_some(if r < 0.9 { 0.0 } else { 0.6 }));
    let json = format!(
        r#"{{"rocks": [{{"cell_m": {cell_m}, "origin": [{}, {}], "rows": {cols}, "cols": {cols}, "bottom_m": {bottom}, "top_m": {top}}}]}}"#,
        origin[0], origin[1]
    );
    let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
    let plan = crate::world::WorldPlan {
        ground_truth: floor.clone(),
        floor,
        boulders: vec![],
        surveyed_rocks: crate::rock_survey::read_rock_survey(json.as_bytes()).unwrap(),
        samples: vec![],
        start: crate::world::StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 },
        ground: crate::world::Ground::Generated { salt: 0 },
    };
    World::build(plan)
}

#[test]
fn surveyed_rocks_are_drawn_where_their_rays_meet_their_columns() {
    let world = world_with_a_surveyed_rock();
    let camera = CameraModel::rover();
    for pose in [
        BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() },
        BodyPose { x_m: 101.0, y_m: 98.0, yaw_deg: 35.0, ..Default::default() },
        BodyPose { x_m: 100.5, y_m: 100.0, ground_m: 1.0, ..Default::default() },
    ] {
        let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
        let mut renderer = Renderer::new(&world, camera, options);
        renderer.render(&world, &[], &pose, &mut RgbImage::default());
        let view = LevelView::new(&camera, camera.position(&pose), pose.yaw_deg);
        let rock = &world.surveyed_rocks()[0];
        let (mut rock_pixels, mut disagreements, mut floor_under_rim) = (0, 0, 0);
        for (index, hit) in renderer.hits().iter().enumerate() {
            let (u, v) = (index % 320 + MARGIN_PX, index / 320 + MARGIN_PX);
            let [dx, dy] = view.column_direction(u);
            let rise = view.row_rise(v);
            let inside = |t: f64| {
                let p = view.camera + nalgebra::Vector3::new(dx, dy, rise) * t;
                rock.column_at(p.x, p.y).is_some_and(|c| (c.bottom_m as f64..=c.top_m as f64).contains(&p.z))
            };
            let nearest = (1..4000).map(|k| k as f64 * 0.002).find(|&t| inside(t));
            let agrees = match (hit.surface == Surface::Boulder, nearest) {
                (true, Some(t)) => (hit.depth_m as f64 - t).abs() < 0.01 + 0.01 * t,
                (false, Some(t)) => t >= hit.depth_m as f64 - 0.01,
                (true, None) => false,
                (false, None) => true,
            };
            rock_pixels += (hit.surface == Surface::Boulder) as usize;
            disagreements += !agrees as usize;
            let p = view.camera + nalgebra::Vector3::new(dx, dy, rise) * hit.depth_m as f64;
            floor_under_rim += (hit.surface == Surface::Floor && rock.column_at(p.x, p.y).is_some()) as usize;
        }
        assert!(rock_pixels > 3000, "{rock_pixels} rock pixels");
        assert!(disagreements * 100 < rock_pixels, "{disagreements} of {rock_pixels} pixels disagree");
        if pose.ground_m == 0.0 {
            assert!(floor_under_rim > 50, "the floor shows under the raised rim: {floor_under_rim} pixels");
        }
    }
}

/// The body at the start of `world` on level ground, with the given yaw, pitch and roll.
fn at_start(world: &World, yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> BodyPose {
    BodyPose { x_m: world.start.x_m, y_m: world.start.y_m, yaw_deg, pitch_deg, roll_deg, ground_m: 0.0 }
}

#[test]
fn a_rover_that_has_not_moved_sees_what_a_fresh_drawing_shows() {
    let world = crate::procgen::procedural_world(3);
    let here = at_start(&world, 10.0, 1.5, 0.0);
    let elsewhere = BodyPose { yaw_deg: 100.0, ..here };
    let sample = Sample { x_m: here.x_m + 3.0, y_m: here.y_m + 0.5, radius_m: 0.2 };
    let second_frame = |first: (&BodyPose, &[Sample]), second: (&BodyPose, &[Sample])| {
        let mut renderer = Renderer::new(&world, CameraModel::rover(), RenderOptions::default());
        let mut image = RgbImage::default();
        renderer.render(&world, first.1, first.0, &mut image);
        renderer.render(&world, second.1, second.0, &mut image);
        image
    };
    let kept = second_frame((&here, &[sample]), (&here, &[sample]));
    assert_eq!(kept.data, second_frame((&elsewhere, &[sample]), (&here, &[sample])).data);
    let picked_up = second_frame((&here, &[sample]), (&here, &[]));
    assert_eq!(picked_up.data, second_frame((&elsewhere, &[]), (&here, &[])).data);
    assert_ne!(kept.data, picked_up.data, "the sample is in view");
}

/// The frame of `world` with its samples from `pose`, drawn by a renderer that `configure` set up.
fn frame_of(world: &World, pose: &BodyPose, configure: impl FnOnce(&mut Renderer)) -> RgbImage {
    let mut renderer = Renderer::new(world, CameraModel::rover(), RenderOptions::default());
    configure(&mut renderer);
    let mut image = RgbImage::default();
    renderer.render(world, &world.samples, pose, &mut image);
    image
}

#[test]
fn blended_columns_look_like_drawn_ones() {
    let (mut byte_difference, mut bytes, mut far_off_pixels) = (0u64, 0u64, 0usize);
    for seed in [1, 2, 3] {
        let world = crate::procgen::procedural_world(seed);
        for yaw_deg in [0.0, 70.0, 160.0, 250.0] {
            let pose = at_start(&world, yaw_deg, 1.0, -1.5);
            let frame_with = |blend_columns| frame_of(&world, &pose, |r| r.blend_columns = blend_columns);
            let (blended, drawn) = (frame_with(true), frame_with(false));
            assert_ne!(blended.data, drawn.data, "seed {seed} yaw {yaw_deg}: nothing blended");
            for (b, d) in blended.data.chunks_exact(3).zip(drawn.data.chunks_exact(3)) {
                let differences = [0, 1, 2].map(|c| b[c].abs_diff(d[c]));
                byte_difference += differences.iter().map(|&x| x as u64).sum::<u64>();
                bytes += 3;
                far_off_pixels += (differences.into_iter().max().unwrap() > 48) as usize;
            }
        }
    }
    let (mean, far_off) = (byte_difference as f64 / bytes as f64, far_off_pixels as f64 / (bytes / 3) as f64);
    assert!(mean < 1.0, "blended frames differ by {mean:.2} levels a byte on average");
    assert!(far_off < 0.005, "{:.2} % of the pixels differ by more than 48 levels", far_off * 100.0);
}

#[test]
fn a_sample_in_view_shows_as_well_in_blended_columns() {
    let world = crate::procgen::procedural_world(2);
    let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
    let mut renderers = [true, false].map(|blend_columns| {
        let mut renderer = Renderer::new(&world, CameraModel::rover(), options);
        renderer.blend_columns = blend_columns;
        renderer
    });
    let (mut views, mut blended_pixels, mut drawn_pixels) = (0, 0, 0);
    for sample in &world.samples {
        for bearing_deg in (0..24).map(|k| k as f64 * 15.0) {
            for distance_m in [2.0, 3.0, 4.5, 6.0, 8.0] {
                let (sin, cos) = bearing_deg.to_radians().sin_cos();
                let (x_m, y_m) = (sample.x_m + distance_m * cos, sample.y_m + distance_m * sin);
                if !world.is_drivable(x_m, y_m) {
                    continue;
                }
                let ground_m = world.ground_height(x_m, y_m) as f64;
                let yaw_deg = bearing_deg + 180.0 + 10.0;
                let pose = BodyPose { x_m, y_m, yaw_deg, pitch_deg: 0.5, roll_deg: -0.5, ground_m };
                let [blended, drawn] = renderers.each_mut().map(|renderer| {
                    renderer.render(&world, &world.samples, &pose, &mut RgbImage::default());
                    renderer.hits().iter().filter(|hit| hit.surface == Surface::Sample).count()
                });
                if drawn > 0 {
                    assert!(
                        blended > 0,
                        "the sample at ({:.1}, {:.1}) is lost from ({x_m:.1}, {y_m:.1})",
                        sample.x_m,
                        sample.y_m
                    );
                    (views, blended_pixels, drawn_pixels) = (views + 1, blended_pixels + blended, drawn_pixels + drawn);
                }
            }
        }
    }
    assert!(views > 100, "{views} views show a sample");
    assert!(blended_pixels * 100 >= drawn_pixels * 99, "{blended_pixels} sample pixels blended, {drawn_pixels} drawn");
}

#[test]
fn threads_draw_the_same_frame_as_one() {
    let world = crate::procgen::procedural_world(2);
    let pose = at_start(&world, 30.0, 3.0, -2.0);
    let frame_with = |threads| frame_of(&world, &pose, |r| r.threads = threads);
    let one = frame_with(1);
    assert_eq!(one.data, frame_with(2).data);
    assert_eq!(one.data, frame_with(3).data);
}
