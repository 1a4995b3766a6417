use super::*;
use crate::world::{StartPose, WORLD_SIZE};

/// Floor on cells 20..180 in x and y, walls around.
fn open_world() -> World {
    World::open(crate::world::rectangle(20..180, 20..180), StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 })
}

fn drive(throttle: f64, brake: f64, steering_deg: f64) -> Command {
    Command::Drive { steering_deg, throttle, brake }
}

#[test]
fn full_throttle_from_rest_accelerates_about_0_8_and_caps_at_5() {
    let world = open_world();
    let mut rover = Rover::new(30.0, 100.0, 0.0);
    rover.apply(drive(1.0, 0.0, 0.0), &[]);
    rover.step(1.0, &world, &[]);
    assert!((0.75..=0.9).contains(&rover.speed_mps), "speed after 1 s: {}", rover.speed_mps);
    rover.step(30.0, &world, &[]);
    assert!((rover.speed_mps - 5.0).abs() < 1e-9, "capped at {}", rover.speed_mps);
    assert!(rover.pitch_deg.abs() < 0.2, "no pitch at constant speed: {}", rover.pitch_deg);
}

#[test]
fn turns_in_place_at_45_degrees_per_second_left_for_positive_steering() {
    let world = open_world();
    let mut rover = Rover::new(100.0, 100.0, 10.0);
    rover.apply(drive(0.0, 0.0, 15.0), &[]);
    rover.step(2.0, &world, &[]);
    assert!((rover.yaw_deg - 100.0).abs() < 1e-6, "yaw {}", rover.yaw_deg);
    assert_eq!((rover.x_m, rover.y_m), (100.0, 100.0));
    rover.apply(drive(0.0, 0.0, -7.5), &[]);
    rover.step(1.0, &world, &[]);
    assert!((rover.yaw_deg - 77.5).abs() < 1e-6, "half steer turns at 22.5 deg/s: {}", rover.yaw_deg);
}

#[test]
fn steering_shrinks_with_speed() {
    let world = open_world();
    let mut rover = Rover::new(100.0, 60.0, 90.0);
    rover.speed_mps = 4.3;
    rover.apply(drive(0.14 * 4.3 / 0.944, 0.0, -15.0), &[]);
    let before = rover.yaw_deg;
    rover.step(0.2, &world, &[]);
    let rate = (rover.yaw_deg - before) / 0.2;
    assert!((-40.0..=-33.0).contains(&rate), "yaw rate {rate} deg/s at 4.3 m/s and full right steer");
    assert!(rover.roll_deg < 0.0, "turning right rolls the left side down: {}", rover.roll_deg);
}

#[test]
fn accelerating_pitches_the_nose_down_and_braking_stops() {
    let world = open_world();
    let mut rover = Rover::new(30.0, 100.0, 0.0);
    rover.apply(drive(1.0, 0.0, 0.0), &[]);
    rover.step(0.8, &world, &[]);
    assert!((0.8..=1.6).contains(&rover.pitch_deg), "pitch {}", rover.pitch_deg);
    rover.step(3.0, &world, &[]);
    rover.apply(drive(0.0, 10.0, 0.0), &[]);
    rover.step(0.3, &world, &[]);
    assert!(rover.pitch_deg < 0.0, "braking pitches the nose up: {}", rover.pitch_deg);
    rover.step(1.0, &world, &[]);
    assert_eq!(rover.speed_mps, 0.0);
}

#[test]
fn a_rover_between_two_mounds_is_never_wedged() {
    let floor = (0..WORLD_SIZE * WORLD_SIZE).map(|i| i != 83 * WORLD_SIZE + 28 && i != 81 * WORLD_SIZE + 29).collect();
    let world = World::open(floor, StartPose { x_m: 29.0, y_m: 82.5, yaw_deg: 0.0 });
    let mut poses = 0;
    for (ix, iy) in (0..20).flat_map(|ix| (0..20).map(move |iy| (ix, iy))) {
        let (x, y) = (28.0 + ix as f64 * 0.1, 81.5 + iy as f64 * 0.1);
        if footprint_blocked(&world, &[], x, y, FOOTPRINT_RADIUS_M) {
            continue;
        }
        poses += 1;
        let headings = [0.0, 33.0, 90.0, 123.0, 180.0, 213.0, 270.0, 303.0];
        let escapes = headings.iter().filter(|&&yaw| {
            let mut rover = Rover::new(x, y, yaw);
            rover.apply(drive(0.8, 0.0, 0.0), &[]);
            for _ in 0..50 {
                rover.step(0.04, &world, &[]);
            }
            (rover.x_m - x).hypot(rover.y_m - y) > 0.3
        });
        assert!(escapes.count() >= 2, "wedged at ({x:.1}, {y:.1}): turning in place frees it in fewer than two ways");
    }
    assert!(poses > 30, "{poses} free poses around the gap");
}

#[test]
fn walls_and_samples_stop_the_rover() {
    let world = open_world();
    let mut rover = Rover::new(170.0, 100.0, 0.0);
    rover.apply(drive(1.0, 0.0, 0.0), &[]);
    let mut collisions = 0;
    for _ in 0..400 {
        collisions += rover.step(0.04, &world, &[]).1.collision as u32;
    }
    assert!((179.0..180.5 - FOOTPRINT_RADIUS_M).contains(&rover.x_m), "stopped at the wall's foot: x = {}", rover.x_m);
    assert_eq!(collisions, 1, "one collision while pushing against the wall");
    let mut glancing = Rover::new(100.0, 179.0, 10.0);
    glancing.apply(drive(1.0, 0.0, 0.0), &[]);
    let mut glancing_collisions = 0;
    for _ in 0..200 {
        glancing_collisions += glancing.step(0.04, &world, &[]).1.collision as u32;
    }
    assert!(glancing.x_m > 102.0, "slides along a wall it meets at a shallow angle: x = {}", glancing.x_m);
    assert!(glancing.y_m < 180.5 - FOOTPRINT_RADIUS_M);
    assert_eq!(glancing_collisions, 0, "a glancing contact is not a collision");
    let sample = [Sample { x_m: 110.0, y_m: 50.0, radius_m: 0.1 }];
    let mut rover = Rover::new(100.0, 50.0, 0.0);
    rover.apply(drive(1.0, 0.0, 0.0), &sample);
    rover.step(20.0, &world, &sample);
    assert!(rover.x_m < 110.0 - FOOTPRINT_RADIUS_M, "cannot drive through a sample: x = {}", rover.x_m);
}

#[test]
fn the_body_follows_the_foot_of_a_wall_but_cannot_climb_it() {
    let world = open_world();
    let mut tilted = 0;
    for x in (30..=170).step_by(10) {
        let mut rover = Rover::new(x as f64, 176.0, 80.0);
        rover.apply(drive(0.6, 0.0, 0.0), &[]);
        let (mut steepest_pitch, mut steepest_roll) = (0.0f64, 0.0f64);
        for _ in 0..300 {
            rover.step(0.04, &world, &[]);
            steepest_pitch = steepest_pitch.min(rover.pitch_deg);
            steepest_roll = steepest_roll.max(rover.roll_deg);
        }
        assert!(rover.y_m < 180.5, "stopped at the foot: y = {}", rover.y_m);
        assert!(rover.ground_m < 0.15, "on the foot, not up the wall: {} m", rover.ground_m);
        if rover.ground_m > 0.01 && steepest_pitch < -2.0 && steepest_roll > 0.3 {
            tilted += 1;
        }
    }
    assert!(tilted >= 3, "where the foot is gentle, the nose and the left wheels rise on it: {tilted} of 15 places");
    let mut flat = Rover::new(100.0, 100.0, 80.0);
    flat.follow_ground(&world);
    assert_eq!((flat.pitch_deg, flat.roll_deg, flat.ground_m), (0.0, 0.0, 0.0));
}

#[test]
fn pickup_takes_ten_seconds_and_needs_a_sample_in_reach() {
    let world = open_world();
    let samples = [Sample { x_m: 100.7, y_m: 100.0, radius_m: 0.09 }];
    let mut far = Rover::new(90.0, 100.0, 0.0);
    far.apply(Command::Pickup, &samples);
    assert!(!far.picking_up, "no sample near: pickup ignored");
    let mut rover = Rover::new(100.0, 100.0, 0.0);
    rover.step(0.04, &world, &samples);
    assert!(rover.near_sample);
    rover.apply(Command::Pickup, &samples);
    assert!(rover.picking_up);
    rover.apply(drive(1.0, 0.0, 0.0), &samples);
    let (picked, _) = rover.step(9.96, &world, &samples);
    assert_eq!(picked, None);
    assert_eq!(rover.speed_mps, 0.0, "drive commands are ignored while picking up");
    let (picked, _) = rover.step(0.04, &world, &samples);
    assert_eq!(picked, Some(0), "done after 10 s");
    assert!(rover.picking_up && !rover.near_sample, "picking_up clears one frame later");
    rover.step(0.04, &world, &[]);
    assert!(!rover.picking_up);
}

#[test]
fn fixed_turn_rotates_clockwise_when_idle() {
    let world = open_world();
    let mut rover = Rover::new(100.0, 100.0, 90.0);
    rover.apply(Command::FixedTurn { angle_deg: 90.0, time_s: 0.0 }, &[]);
    rover.apply(drive(1.0, 0.0, 0.0), &[]);
    rover.step(2.0, &world, &[]);
    assert!(rover.yaw_deg.abs() < 1e-6 || (rover.yaw_deg - 360.0).abs() < 1e-6, "yaw {}", rover.yaw_deg);
    assert_eq!((rover.x_m, rover.y_m), (100.0, 100.0));
}
