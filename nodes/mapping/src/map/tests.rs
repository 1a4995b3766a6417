use super::*;

/// Needs two navigable frames and twice as many navigable as obstacle frames.
const STRICT: MapConfig = MapConfig {
    max_range_m: 8.0,
    max_tilt_deg: 3.0,
    correct_tilt: true,
    min_navigable_hits: 2,
    navigable_ratio: 2.0,
    full_weight_range_m: 8.0,
    shadow_margin_m: 20.0,
    min_obstacle_hits: 2,
    min_rock_hits: 2,
};

fn scan(cells: &[u8], rows: usize, cols: usize) -> ScanGrid<'_> {
    ScanGrid { rows, cols, resolution_m: 0.5, origin_x_m: 1.0, origin_y_m: -0.5 * cols as f64 / 2.0, cells }
}

#[test]
fn a_cell_is_counted_once_per_frame_and_needs_two_frames() {
    let cells = vec![NAVIGABLE; 4 * 4];
    let pose = Pose { x_m: 100.0, y_m: 100.0, ..Pose::default() };
    let mut map = WorldMap::new(STRICT);
    assert_eq!(map.update(&scan(&cells, 4, 4), pose), Update::Used(16));
    let cell = cell_of_point(101.8, 100.2).unwrap();
    assert_eq!(map.evidence(cell), (1, 0, 0), "four scan cells in one map cell count once");
    assert_ne!(map.cell_occupancy(cell), OCCUPANCY_FREE);
    map.update(&scan(&cells, 4, 4), pose);
    assert_eq!(map.cell_occupancy(cell), OCCUPANCY_FREE);
    assert_eq!(map.occupancy()[cell], 0);
}

#[test]
fn a_new_range_limit_applies_from_the_next_frame() {
    let cells = vec![NAVIGABLE; 16 * 2];
    let pose = Pose { x_m: 100.0, y_m: 100.0, ..Pose::default() };
    let mut map = WorldMap::new(STRICT);
    assert_eq!(map.update(&scan(&cells, 16, 2), pose), Update::Used(28), "rows 1.25..7.75 m ahead");
    map.set_config(MapConfig { max_range_m: 3.0, ..STRICT });
    assert_eq!(map.update(&scan(&cells, 16, 2), pose), Update::Used(8), "rows 1.25..2.75 m ahead");
    map.set_config(STRICT);
    assert_eq!(map.update(&scan(&cells, 16, 2), pose), Update::Used(28));
}

#[test]
fn obstacles_outvote_and_tilted_frames_are_skipped() {
    let pose = Pose { x_m: 50.0, y_m: 50.0, ..Pose::default() };
    let mut map = WorldMap::new(STRICT);
    for _ in 0..3 {
        map.update(&scan(&[rover_msgs::msg::TerrainScan::OBSTACLE; 16], 4, 4), pose);
    }
    map.update(&scan(&[NAVIGABLE; 16], 4, 4), pose);
    let cell = cell_of_point(51.8, 50.2).unwrap();
    assert_eq!(map.cell_occupancy(cell), OCCUPANCY_OCCUPIED);
    assert_eq!(map.occupancy()[cell], 100);
    let tilted = Pose { pitch_rad: 5f64.to_radians(), ..pose };
    assert_eq!(map.update(&scan(&[NAVIGABLE; 16], 4, 4), tilted), Update::SkippedTilt);
    assert_eq!(map.update(&scan(&[NAVIGABLE; 3], 4, 4), pose), Update::Malformed);
}

#[test]
fn near_frames_outweigh_far_ones() {
    let (rows, cols) = (16, 2);
    let class_in_row = |row: usize, class: u8| {
        let mut cells = vec![0; rows * cols];
        cells[row * cols..(row + 1) * cols].fill(class);
        cells
    };
    let (near, far) = (class_in_row(2, NAVIGABLE), class_in_row(12, rover_msgs::msg::TerrainScan::OBSTACLE));
    let observe = |config: MapConfig| {
        let mut map = WorldMap::new(config);
        for _ in 0..3 {
            map.update(&scan(&near, rows, cols), Pose { x_m: 28.5, y_m: 20.5, ..Pose::default() });
        }
        for _ in 0..6 {
            map.update(&scan(&far, rows, cols), Pose { x_m: 23.5, y_m: 20.5, ..Pose::default() });
        }
        map
    };
    let cell = cell_of_point(30.5, 20.5).unwrap();
    let config = MapConfig { navigable_ratio: 1.0, ..MapConfig::default() };
    let map = observe(config);
    assert_eq!(map.evidence(cell), (3, 6, 0), "each frame counts once");
    let (navigable, obstacle) = map.weighed_evidence(cell);
    assert!((navigable - 3.0).abs() < 1e-6, "seen from 2.25 m: full weight, {navigable}");
    let far_weight = (3.0f32 / 7.25).powi(2);
    assert!((obstacle / (6.0 * far_weight) - 1.0).abs() < 0.01, "seen from 7.25 m: {obstacle}");
    assert_eq!(map.cell_occupancy(cell), OCCUPANCY_FREE, "three near frames outweigh six far ones");
    let unweighed = observe(MapConfig { full_weight_range_m: 20.0, ..config });
    assert_eq!(unweighed.cell_occupancy(cell), OCCUPANCY_OCCUPIED, "counted alike, the six far frames win");
}

#[test]
fn rocks_are_found_and_cleared() {
    let pose = Pose { x_m: 20.0, y_m: 20.0, ..Pose::default() };
    let mut cells = vec![NAVIGABLE; 16];
    cells[5] = ROCK;
    let mut map = WorldMap::new(MapConfig::default());
    map.update(&scan(&cells, 4, 4), pose);
    map.update(&scan(&cells, 4, 4), pose);
    let rocks = map.rock_cells();
    assert_eq!(rocks.len(), 1, "{rocks:?}");
    map.clear_rocks_near(rocks[0].0 as f64 + 0.5, rocks[0].1 as f64 + 0.5, 1.0);
    assert!(map.rock_cells().is_empty());
}

#[test]
fn a_rock_seen_far_then_near_is_placed_where_it_was_seen_near() {
    let (rows, cols) = (12, 4);
    let rock_in_row = |row: usize| {
        let mut cells = vec![NAVIGABLE; rows * cols];
        cells[row * cols + 1] = ROCK;
        cells
    };
    let mut map = WorldMap::new(MapConfig::default());
    let (far, near) = (rock_in_row(11), rock_in_row(1));
    for _ in 0..2 {
        map.update(&scan(&far, rows, cols), Pose { x_m: 20.0, y_m: 20.5, ..Pose::default() });
    }
    assert_eq!(map.rocks(&map.occupancy(), 3.5), vec![(26.5, 20.5)], "seen from 6.75 m");
    for _ in 0..2 {
        map.update(&scan(&near, rows, cols), Pose { x_m: 22.0, y_m: 20.5, ..Pose::default() });
    }
    assert_eq!(map.rock_cells().len(), 2);
    assert_eq!(map.rocks(&map.occupancy(), 3.5), vec![(23.5, 20.5)], "seen from 1.75 m, the far echo merged into it");
}

#[test]
fn obstacles_far_behind_the_nearest_one_of_their_bearing_are_not_evidence() {
    let (rows, cols) = (12, 1);
    let mut cells = vec![0; rows * cols];
    cells[2 * cols..3 * cols].fill(OBSTACLE);
    cells[4 * cols..5 * cols].fill(OBSTACLE);
    cells[10 * cols..11 * cols].fill(OBSTACLE);
    let obstacle_frames = |shadow_margin_m: f64| {
        let mut map = WorldMap::new(MapConfig { shadow_margin_m, ..STRICT });
        map.update(&scan(&cells, rows, cols), Pose { x_m: 20.0, y_m: 20.5, ..Pose::default() });
        [2.25, 3.25, 6.25].map(|ahead_m| map.evidence(cell_of_point(20.0 + ahead_m, 20.5).unwrap()).1)
    };
    assert_eq!(obstacle_frames(20.0), [1, 1, 1], "every obstacle cell counts");
    assert_eq!(obstacle_frames(1.5), [1, 1, 0], "the wall and 1.5 m behind it count, the far face does not");
}

#[test]
fn a_rock_far_into_a_wall_is_an_echo_and_one_at_its_foot_a_rock() {
    let (rows, cols) = (14, 4);
    let rocks_with_rock_in_row = |row: usize| {
        let mut cells: Vec<u8> = (0..rows * cols).map(|i| if i / cols < 4 { NAVIGABLE } else { OBSTACLE }).collect();
        cells[row * cols + 1] = ROCK;
        let mut map = WorldMap::new(STRICT);
        for _ in 0..2 {
            map.update(&scan(&cells, rows, cols), Pose { x_m: 20.0, y_m: 20.5, ..Pose::default() });
        }
        assert_eq!(map.rock_cells().len(), 1, "the rock cell is mapped either way");
        map.rocks(&map.occupancy(), 3.5)
    };
    assert_eq!(rocks_with_rock_in_row(5), vec![(23.5, 20.5)], "1 m beyond the floor");
    assert!(rocks_with_rock_in_row(12).is_empty(), "5 m into the wall");
}

#[test]
fn range_limit_drops_far_cells() {
    let config = MapConfig { max_range_m: 1.5, ..MapConfig::default() };
    let mut map = WorldMap::new(config);
    let Update::Used(landed) =
        map.update(&scan(&[NAVIGABLE; 16], 4, 4), Pose { x_m: 9.0, y_m: 9.0, ..Pose::default() })
    else {
        panic!("frame used");
    };
    assert!(landed < 16, "{landed}");
}
