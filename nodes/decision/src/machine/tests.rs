//! The machine's behaviour, mode by mode, on small maps.

use std::sync::Arc;

use rover_msgs::body::ARM_REACH_M;
use rover_msgs::map_grid::{CELLS, cell_at, cell_centre_m, cell_of_point};

use super::*;

use crate::approach::UNSEEN_S;
use crate::arrivals::ARRIVAL_DELAY_FRAMES;
use crate::drive::speed_to_stop_in;
use crate::grid::Cell;
use crate::route::PlanningMap;
use crate::samples::APPROACHES_PER_ROCK;
use crate::stuck::STUCK_MARK_S;

fn open_ahead() -> FreeSpace {
    FreeSpace { directions_rad: vec![-0.3, 0.0, 0.3], free_m: vec![6.0, 6.0, 6.0] }
}

fn observation(frame: u64, x_m: f64, y_m: f64) -> Observation {
    Observation {
        frame,
        position: Position { x_m, y_m, yaw_rad: 0.0 },
        pitch_rad: 0.0,
        roll_rad: 0.0,
        speed_mps: 0.0,
        near_sample: false,
        picking_up: false,
        samples_remaining: 6,
        free: open_ahead(),
        rock: None,
    }
}

/// A machine with the default parameters that has received `map`.
fn machine_on(map: Grid) -> Machine {
    machine_on_with(map, DecisionParams::default())
}

/// A machine with `params` that has received `map`.
fn machine_on_with(map: Grid, params: DecisionParams) -> Machine {
    let mut machine = Machine::new(params);
    machine.set_map(map);
    machine
}

/// A corridor along y = 100 from x = 90 to 130, unknown beyond x = 130.
fn corridor() -> Grid {
    let mut data = vec![100i8; CELLS];
    for y in 98..103 {
        for x in 90..140 {
            data[cell_at(x, y)] = if x < 130 { 0 } else { -1 };
        }
    }
    Grid::from_occupancy(&data).unwrap()
}

#[test]
fn a_map_without_free_cells_does_not_end_the_exploration() {
    let params = DecisionParams::default();
    let mut machine = machine_on(Grid::unknown());
    for frame in 1..params.frames(params.stuck_s) {
        let drive = machine.step(&observation(frame, 100.5, 100.5));
        assert!(drive.throttle > 0.0, "frame {frame}: {drive:?}");
    }
    assert_eq!(machine.status().mode, Mode::Explore);
}

#[test]
fn a_map_that_shows_no_ground_after_a_look_around_is_waited_for_not_concluded_from() {
    let params = DecisionParams::default();
    let mut machine = machine_on(Grid::unknown());
    let mut yaw_rad = 0.0;
    let mut braked_frames = 0;
    for frame in 1..params.frames(120.0) {
        let obs =
            Observation { position: Position { x_m: 100.5, y_m: 100.5, yaw_rad }, ..observation(frame, 0.0, 0.0) };
        let drive = machine.step(&obs);
        yaw_rad = crate::pose::wrap_rad(yaw_rad + drive.steering_deg.signum() * 0.05);
        braked_frames += usize::from(drive.brake > 0.0);
        assert!(!matches!(machine.status().mode, Mode::ReturnHome | Mode::Done), "frame {frame}: {drive:?}");
    }
    assert!(braked_frames > params.frames(60.0) as usize, "the rover waits braked: {braked_frames} frames");
    machine.set_map(corridor());
    let drive = machine.step(&observation(params.frames(120.0), 100.5, 100.5));
    assert!(drive.throttle > 0.0, "a map showing the corridor: the rover explores it: {drive:?}");
}

#[test]
fn a_rover_that_the_map_walls_in_backs_out_instead_of_giving_the_frontiers_up() {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    let among_rock_cells = observation(1, 110.5, 106.5);
    machine.step(&among_rock_cells);
    assert_eq!(machine.status().mode, Mode::Recover, "{:?}", machine.status());
    assert!(machine.status().reason.contains("walled in"), "{:?}", machine.status());
    let mut in_the_corridor = Machine::new(params);
    in_the_corridor.set_map(corridor());
    in_the_corridor.step(&observation(1, 110.5, 100.5));
    assert_eq!(in_the_corridor.status().mode, Mode::Explore);
}

#[test]
fn a_recalled_machine_keeps_what_the_exploration_learnt_and_the_way_home() {
    let params = DecisionParams::default();
    let mut first = machine_on(corridor());
    for frame in 1..50 {
        first.step(&observation(frame, 100.5 + frame as f64 * 0.1, 100.5));
    }
    let learnt = first.recollection();
    assert!(learnt.explorer.inspected.iter().any(|&cell| cell), "the camera saw cells up close");
    let mut second = Machine::new(params);
    second.recall(learnt.clone());
    assert_eq!(second.recollection(), learnt);
    second.recall(Recollection { stage: Stage::ReturningHome, ..learnt });
    assert_eq!(second.status().mode, Mode::ReturnHome);
}

/// A machine recalled at `stage` from one whose home is (100.5, 100.5), on the corridor map,
/// that has been stepped for ten frames at (`x_m`, 100.5) before the mission reached it:
/// it braked in `mode` on every one.
fn recalled_and_braked(stage: Stage, x_m: f64, mode: Mode) -> Machine {
    let mut first = machine_on(corridor());
    first.step(&observation(1, 100.5, 100.5));
    let mut second = machine_on(corridor());
    second.recall(Recollection { stage, ..first.recollection() });
    for frame in 100..110 {
        let drive = second.step(&observation(frame, x_m, 100.5));
        assert_eq!((drive.throttle, second.status().mode), (0.0, mode), "frame {frame}");
        assert!(drive.brake > 0.0, "brakes while the mission is unknown");
    }
    second
}

#[test]
fn a_machine_recalled_while_exploring_brakes_until_the_mission_arrives_then_explores() {
    let mut machine = recalled_and_braked(Stage::Exploring, 104.5, Mode::Explore);
    machine.resume(Memory { home: (100.5, 100.5), samples_collected: 2 });
    let drive = machine.step(&observation(110, 104.5, 100.5));
    let moves = drive.throttle > 0.0 || drive.steering_deg != 0.0;
    assert!(moves && drive.brake == 0.0 && machine.status().mode == Mode::Explore, "explores: {drive:?}");
}

#[test]
fn a_machine_recalled_on_the_way_home_waits_for_the_missions_home_before_it_is_done() {
    let mut machine = recalled_and_braked(Stage::ReturningHome, 110.5, Mode::ReturnHome);
    machine.resume(Memory { home: (100.5, 100.5), samples_collected: 6 });
    let drive = machine.step(&observation(110, 110.5, 100.5));
    assert_eq!(machine.status().mode, Mode::ReturnHome, "10 m from home is not home");
    assert_eq!(machine.status().home, Some((100.5, 100.5)));
    assert!(drive.brake == 0.0, "{drive:?}");
}

#[test]
fn the_path_followed_while_exploring_leads_to_the_frontier_target() {
    let mut machine = machine_on(corridor());
    assert!(machine.path().is_empty(), "no plan before the first frame");
    machine.step(&observation(1, 100.5, 100.5));
    let path = machine.path();
    let (first, last) = (cell_centre_m(path[0]), cell_centre_m(path[path.len() - 1]));
    assert_eq!(first, (100.5, 100.5), "from the rover's cell");
    assert_eq!(Some(last), machine.explorer.target(), "to the target");
}

#[test]
fn a_rover_that_turns_on_one_spot_for_long_recovers() {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    let facing_away = |frame| {
        let mut obs = observation(frame, 91.5, 100.5);
        obs.position.yaw_rad = std::f64::consts::PI;
        obs
    };
    let stall = params.frames(params.stall_s);
    for frame in 1..stall {
        assert_eq!(machine.step(&facing_away(frame)).throttle, 0.0, "turns in place");
        assert_eq!(machine.status().mode, Mode::Explore, "frame {frame}");
    }
    machine.step(&facing_away(stall + 1));
    assert_eq!((machine.status().mode, machine.status().reason.as_str()), (Mode::Recover, "no progress"));
}

#[test]
fn a_seen_sample_is_approached_and_picked_up() {
    let mut machine = Machine::new(DecisionParams::default());
    machine.set_map(corridor());
    let mut obs = observation(1, 100.5, 100.5);
    obs.rock = Some(Sighting { bearing_rad: 0.1, distance_m: 3.0 });
    machine.step(&obs);
    assert_eq!(machine.status().mode, Mode::ApproachSample);
    obs.frame = 2;
    obs.near_sample = true;
    assert_eq!(machine.step(&obs).throttle, 0.0);
    assert_eq!(machine.status().mode, Mode::Pickup);
    obs.frame = 3;
    obs.picking_up = true;
    machine.step(&obs);
    obs.frame = 4;
    (obs.picking_up, obs.near_sample, obs.samples_remaining, obs.rock) = (false, false, 5, None);
    machine.step(&obs);
    assert_eq!(machine.status().mode, Mode::Explore);
    assert_eq!((machine.status().reason.as_str(), machine.status().samples_collected), ("sample collected", 1));
}

#[test]
fn a_sample_ahead_is_approached_as_fast_as_braking_leaves_it_in_reach() {
    let params = DecisionParams::default();
    let speed_toward = |distance_m: f64, speed_mps: f64| {
        let mut machine = machine_on(corridor());
        let mut obs = observation(1, 100.5, 100.5);
        (obs.rock, obs.speed_mps) = (Some(Sighting { bearing_rad: 0.0, distance_m }), speed_mps);
        machine.step(&obs)
    };
    let far = speed_toward(3.5, 2.0);
    assert!(far.throttle > 0.0 && far.brake == 0.0, "2 m/s is safe 3.5 m off: {far:?}");
    let near = speed_toward(1.2, 2.0);
    assert!(near.brake > 0.0, "2 m/s 1.2 m off would overrun the sample: {near:?}");
    let creep = speed_toward(0.9, params.approach_speed_mps * 0.5);
    assert!(creep.throttle > 0.0, "the last metres at the approach speed: {creep:?}");
    let stopping_m = |v: f64| v * v / (2.0 * params.stop_decel_mps2);
    let v = speed_to_stop_in(3.5 - ARM_REACH_M, &params);
    assert!((stopping_m(v) - (3.5 - ARM_REACH_M)).abs() < 1e-9);
}

/// Two corridors along y = 98..103 and y = 106..111 from x = 90 to 140, joined at x = 135..140.
fn two_corridors() -> Grid {
    let mut data = vec![100i8; CELLS];
    for y in (98..103).chain(106..111) {
        for x in 90..140 {
            data[cell_at(x, y)] = 0;
        }
    }
    for y in 103..106 {
        for x in 135..140 {
            data[cell_at(x, y)] = 0;
        }
    }
    Grid::from_occupancy(&data).unwrap()
}

#[test]
fn a_seen_sample_that_the_map_puts_a_long_way_round_is_left_for_later_unless_it_is_the_last() {
    let sample_across_the_wall = |sample_detour_cost: f64, samples_remaining: u8| {
        let mut machine = machine_on_with(two_corridors(), DecisionParams { sample_detour_cost, ..Default::default() });
        machine.set_rocks(vec![(100.5, 107.5)]);
        let mut modes = Vec::new();
        for frame in 1..machine.params.frames(machine.params.stuck_s) {
            let mut obs = Observation { samples_remaining, ..observation(frame, 100.5, 100.5) };
            obs.rock = Some(Sighting { bearing_rad: std::f64::consts::FRAC_PI_2, distance_m: 7.0 });
            machine.step(&obs);
            modes.push(machine.status().mode);
        }
        (modes, machine.status().reason.clone())
    };
    let (modes, reason) = sample_across_the_wall(60.0, 2);
    assert!(modes.iter().all(|&mode| mode == Mode::Explore), "{modes:?}");
    assert_eq!(reason, "sample out of the way on the map");
    let (modes, _) = sample_across_the_wall(200.0, 2);
    assert!(modes.iter().all(|&mode| mode == Mode::ApproachSample), "80 m round is worth 200: {modes:?}");
    let (modes, _) = sample_across_the_wall(60.0, 1);
    assert!(modes.iter().all(|&mode| mode == Mode::ApproachSample), "the last sample missing: {modes:?}");
}

#[test]
fn a_remembered_sample_that_the_camera_places_a_long_way_round_is_left_alone_where_both_put_it() {
    let mut machine = machine_on(two_corridors());
    machine.set_rocks(vec![(110.5, 101.5)]);
    for frame in 1..machine.params.frames(machine.params.stuck_s) {
        let mut obs = Observation { samples_remaining: 2, ..observation(frame, 100.5, 100.5) };
        let across_the_wall = (108.5f64 - 100.5).atan2(107.5 - 100.5);
        obs.rock = Some(Sighting { bearing_rad: across_the_wall, distance_m: 7.0f64.hypot(8.0) });
        machine.step(&obs);
        assert_eq!(machine.status().mode, Mode::Explore, "frame {frame}");
    }
    assert!(machine.is_ignored((110.5, 101.5)) && machine.is_ignored((107.5, 108.5)));
}

#[test]
fn a_remembered_sample_that_the_camera_does_not_see_from_close_by_is_given_up_for_a_while() {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    machine.set_rocks(vec![(102.5, 100.5)]);
    machine.step(&observation(1, 100.5, 100.5));
    let mut given_up = Vec::new();
    for frame in 2..10 * params.frames(UNSEEN_S) {
        machine.step(&observation(frame, 100.5, 100.5));
        if machine.take_change() && machine.status().reason == "sample not where remembered" {
            given_up.push((machine.status().mode, machine.is_ignored((102.5, 100.5))));
        }
    }
    assert_eq!(given_up.len(), APPROACHES_PER_ROCK, "approached and not seen, then given up: {given_up:?}");
    assert_eq!(given_up.last(), Some(&(Mode::Explore, true)), "back to exploring, the sample ignored");
    machine.mission.frame += params.frames(params.sample_retry_s);
    assert!(!machine.is_ignored((102.5, 100.5)), "tried again later");
}

#[test]
fn a_slow_approach_is_not_stuck_a_stopped_rover_is() {
    let params = DecisionParams::default();
    let mut machine = Machine::new(params.clone());
    machine.driving.watches.last_drive = Drive { throttle: 0.2, brake: 0.0, steering_deg: 0.0 };
    let slow = |frame: u64, speed_mps: f64| {
        let mut obs = observation(frame, 100.0 + 0.004 * frame as f64, 100.5);
        obs.speed_mps = speed_mps;
        obs
    };
    let watch = params.frames(params.stuck_s) + 2;
    assert!(
        (1..watch).all(|frame| !machine.driving.watches.stuck(&slow(frame, 0.15), &params)),
        "0.15 m/s, less than 0.3 m in 1.5 s"
    );
    assert!((watch..2 * watch).any(|frame| machine.driving.watches.stuck(&slow(frame, 0.0), &params)), "stopped");
}

#[test]
fn a_rover_that_pushes_against_a_rock_and_turns_in_between_is_stuck() {
    let params = DecisionParams::default();
    let mut machine = Machine::new(params.clone());
    let (push, turn) = (Drive { throttle: 1.0, brake: 0.0, steering_deg: 0.0 }, Drive::turn_in_place(true));
    let stuck_at = (1..20 * params.frames(params.stuck_s)).find(|&frame| {
        machine.driving.watches.last_drive = if frame % 8 < 4 { push } else { turn };
        machine.driving.watches.stuck(&observation(frame, 100.0, 100.5), &params)
    });
    let stuck_at = stuck_at.expect("stuck while alternating pushes and turns");
    assert!(
        stuck_at <= 2 * params.frames(params.stuck_s) + 8,
        "stuck after {stuck_at} frames: about twice the time of a push"
    );
}

#[test]
fn getting_stuck_makes_the_cell_ahead_an_obstacle_until_nothing_else_is_left() {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    let ahead = cell_of_point(101.4, 100.5).unwrap();
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Free);
    machine.mark_stuck_cell(&observation(10, 100.5, 100.5));
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Blocked, "stuck here: the cell ahead is an obstacle");
    assert_eq!(machine.maps.received.cell(ahead), Cell::Free, "the map itself is kept");
    machine.set_map(corridor());
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Blocked, "and stays marked in the next map");
    assert!(machine.maps.forget_stuck_marks() && machine.maps.planning.grid().cell(ahead) == Cell::Free);
    machine.mark_stuck_cell(&observation(300, 100.5, 100.5));
    machine.mission.frame = 300 + params.frames(STUCK_MARK_S) - 1;
    machine.set_map(corridor());
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Blocked, "marked again");
    machine.mission.frame += 1;
    machine.set_map(corridor());
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Free, "until the mark expires");
}

#[test]
fn exploring_keeps_the_stuck_marks_where_forgetting_them_got_the_rover_stuck_again() {
    let mut machine = machine_on(corridor());
    let ahead = cell_of_point(101.4, 100.5).unwrap();
    let stuck_here = observation(10, 100.5, 100.5);
    machine.mark_stuck_cell(&stuck_here);
    assert!(machine.maps.forget_stuck_marks_to_explore(&stuck_here.position), "forgotten the first time");
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Free);
    machine.mark_stuck_cell(&observation(20, 101.0, 100.5));
    assert!(!machine.maps.forget_stuck_marks_to_explore(&observation(21, 101.0, 100.5).position));
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Blocked, "stuck again there: the mark holds");
    assert!(machine.maps.forget_stuck_marks_to_explore(&observation(90, 104.5, 100.5).position), "away from there");
    assert_eq!(machine.maps.planning.grid().cell(ahead), Cell::Free);
}

#[test]
fn a_way_home_that_the_stuck_marks_cut_off_is_planned_again_without_them() {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    machine.step(&observation(1, 100.5, 100.5));
    for y in 98..103 {
        let facing_the_corridor_wall = Position { x_m: 119.5, y_m: y as f64 + 0.5, yaw_rad: 0.0 };
        machine.maps.stuck_marks.note_stuck((&facing_the_corridor_wall, 2), machine.maps.planning.grid(), &[], &params);
        machine.maps.apply_stuck_marks();
    }
    let across = cell_of_point(120.5, 100.5).unwrap();
    assert_eq!(machine.maps.planning.grid().cell(across), Cell::Blocked, "the marks close the corridor");
    machine.enter(State::ReturnHome(None), "test");
    let mut beyond_the_marks = observation(3, 125.5, 100.5);
    beyond_the_marks.position.yaw_rad = std::f64::consts::PI;
    let drive = machine.step(&beyond_the_marks);
    assert_eq!(machine.maps.planning.grid().cell(across), Cell::Free, "the marks are forgotten");
    assert!(!machine.path().is_empty(), "a route home along the corridor");
    assert!(drive.throttle > 0.0 && drive.steering_deg.abs() < 1.0, "straight home: {drive:?}");
}

#[test]
fn a_received_map_is_planned_on_from_the_arrival_delay_after_its_frame() {
    let mut machine = Machine::new(DecisionParams::default());
    machine.receive_map(5, corridor());
    machine.step(&observation(5 + ARRIVAL_DELAY_FRAMES - 1, 100.5, 100.5));
    assert_eq!(machine.maps.received.counts(), Grid::unknown().counts(), "not yet due");
    machine.step(&observation(5 + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
    assert_eq!(machine.maps.received.counts(), corridor().counts(), "due");
}

#[test]
fn after_two_maps_the_planning_map_expects_the_next_as_long_after_the_last() {
    let mut machine = Machine::new(DecisionParams::default());
    for made_at in [5, 30] {
        machine.receive_map(made_at, corridor());
        machine.step(&observation(made_at + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
    }
    assert_eq!(machine.maps.planning.next_map_frame(), Some(55 + ARRIVAL_DELAY_FRAMES));
    machine.receive_map(50, corridor());
    machine.step(&observation(50 + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
    assert_eq!(machine.maps.planning.next_map_frame(), Some(70 + ARRIVAL_DELAY_FRAMES), "a map 20 frames on");
}

/// A machine planning in [`corridor`] at frame 3 that has prepared the next frame, on which
/// a copy of the corridor map takes effect; that frame's observation.
fn prepared_for_a_map_due_next() -> (Machine, Observation) {
    let (mut machine, _) = started_at_home_in_the_corridor();
    let here = observation(3, 100.5, 100.5);
    machine.receive_map(here.frame + 1 - ARRIVAL_DELAY_FRAMES, corridor());
    machine.step(&here);
    machine.prepare_next_frame(&here.position);
    (machine, observation(here.frame + 1, 100.5, 100.5))
}

#[test]
fn the_first_plan_on_a_map_due_next_frame_is_searched_between_frames() {
    let (mut machine, next_frame) = prepared_for_a_map_due_next();
    let version = machine.maps.planning.version();
    let next = machine.maps.next_planning.as_ref().expect("made for the map due next");
    assert_eq!((next.version(), next.made_from()), (version + 1, cell_of_point(100.5, 100.5)));
    let made = next.made_costs().expect("costs made ahead");
    machine.step(&next_frame);
    assert_eq!(machine.maps.planning.version(), version + 1);
    let taken = machine.maps.planning.last_costs().expect("planned on the new map");
    assert!(Arc::ptr_eq(&made, &taken), "the first plan on it took the costs made ahead");
    machine.receive_map(next_frame.frame + 1 - ARRIVAL_DELAY_FRAMES, Grid::unknown());
    machine.prepare_next_frame(&next_frame.position);
    assert!(machine.maps.next_planning.is_none(), "nothing made for a map that will be ignored");
}

#[test]
fn costs_made_ahead_start_where_the_rover_will_be_if_it_keeps_going() {
    let (mut machine, _) = started_at_home_in_the_corridor();
    let before = observation(2, 100.3, 100.5);
    machine.step(&before);
    machine.prepare_next_frame(&before.position);
    let here = observation(3, 100.7, 100.5);
    machine.receive_map(here.frame + 1 - ARRIVAL_DELAY_FRAMES, corridor());
    machine.step(&here);
    machine.prepare_next_frame(&here.position);
    let one_frame_on = cell_of_point(101.1, 100.5);
    assert_ne!(one_frame_on, cell_of_point(100.7, 100.5), "the next frame is in the next cell");
    let next = machine.maps.next_planning.as_ref().expect("made for the map due next");
    assert_eq!(next.made_from(), one_frame_on);
    let made = next.made_costs().expect("costs made ahead");
    machine.step(&observation(here.frame + 1, 101.1, 100.5));
    let taken = machine.maps.planning.last_costs().expect("planned on the new map");
    assert!(Arc::ptr_eq(&made, &taken), "the next frame took the costs made ahead");
}

#[test]
fn a_planning_map_made_ahead_for_another_map_is_not_taken() {
    let (mut machine, next_frame) = prepared_for_a_map_due_next();
    let made = machine.maps.next_planning.as_ref().and_then(PlanningMap::made_costs).expect("made ahead");
    let mut other = corridor();
    other.block(cell_of_point(100.5, 101.5).unwrap());
    machine.receive_map(next_frame.frame - ARRIVAL_DELAY_FRAMES, other.clone());
    machine.step(&next_frame);
    assert!(machine.maps.next_planning.is_none(), "dropped once the frame has begun");
    assert_eq!(*machine.maps.planning.grid(), other, "the newer map");
    let taken = machine.maps.planning.last_costs().expect("planned on the new map");
    assert!(!Arc::ptr_eq(&made, &taken), "searched on the newer map");
}

/// A machine that started its mission at (100.5, 100.5) in [`corridor`], and the frame of its
/// mission deadline.
fn started_at_home_in_the_corridor() -> (Machine, u64) {
    let params = DecisionParams::default();
    let mut machine = machine_on(corridor());
    machine.step(&observation(1, 100.5, 100.5));
    (machine, params.frames(params.mission_deadline_s))
}

#[test]
fn a_rover_stuck_on_the_way_home_recovers_and_goes_on_home() {
    let (mut machine, late) = started_at_home_in_the_corridor();
    machine.step(&observation(late, 120.5, 100.5));
    assert_eq!(machine.status().mode, Mode::ReturnHome);
    let mut frame = late;
    while machine.status().mode == Mode::ReturnHome {
        frame += 1;
        let mut blocked = observation(frame, 120.5, 100.5);
        blocked.position.yaw_rad = std::f64::consts::PI;
        machine.step(&blocked);
        assert!(frame < late + 100, "never stuck");
    }
    assert_eq!((machine.status().mode, machine.status().reason.as_str()), (Mode::Recover, "stuck"));
    while machine.status().mode == Mode::Recover {
        frame += 1;
        machine.step(&observation(frame, 120.0, 100.5));
    }
    assert_eq!(machine.status().mode, Mode::ReturnHome, "after the recovery: {:?}", machine.status());
}

/// Steps `machine` with the rover held at (x, y) facing east until it has entered recover
/// `times` more times; the frame reached.
fn recoveries_at(machine: &mut Machine, mut frame: u64, (x_m, y_m): (f64, f64), times: u32) -> u64 {
    let mut entered = 0;
    while entered < times {
        frame += 1;
        let before = machine.status().mode;
        machine.step(&observation(frame, x_m, y_m));
        entered += u32::from(machine.status().mode == Mode::Recover && before != Mode::Recover);
        assert!(frame < 100_000, "{entered} of {times} recoveries");
    }
    frame
}

#[test]
fn a_rover_stuck_again_and_again_at_one_spot_drives_back_the_way_it_came() {
    let mut machine = machine_on(corridor());
    let mut frame = 0;
    for step in 0..=20 {
        frame += 1;
        machine.step(&observation(frame, 100.5 + 0.5 * f64::from(step), 100.5));
    }
    frame = recoveries_at(&mut machine, frame, (110.5, 100.5), 2);
    let backs_off = machine.step(&observation(frame + 1, 110.5, 100.5));
    assert!(backs_off.throttle < 0.0, "the first recoveries back off: {backs_off:?}");
    frame = recoveries_at(&mut machine, frame + 1, (110.4, 100.5), 1);
    let mut x_m = 110.4;
    while machine.status().mode == Mode::Recover {
        frame += 1;
        let facing_west = Position { x_m, y_m: 100.5, yaw_rad: std::f64::consts::PI };
        let drive = machine.step(&Observation { position: facing_west, ..observation(frame, x_m, 100.5) });
        assert!(drive.throttle >= 0.0 && drive.steering_deg.abs() < 1.0, "x {x_m:.2}: {drive:?}");
        x_m -= 0.02;
        assert!(x_m > 105.0, "the retrace ends");
    }
    assert!(x_m < 107.6, "the third drove back along the trail to 3 m from the spot: x {x_m:.2}");
}

#[test]
fn a_search_for_a_missing_sample_looks_at_the_walls_again_once_then_ends() {
    let mut machine = machine_on(corridor());
    let given_up_and_seen = |machine: &Machine| {
        Explorer::with_memory(ExplorerMemory {
            inspected: vec![true; CELLS],
            explored: vec![true; CELLS],
            ..machine.explorer.memory()
        })
    };
    machine.explorer = given_up_and_seen(&machine);
    assert_eq!(machine.widen_search(0), None, "no sample missing");
    assert_eq!(machine.widen_search(1), Some("trying given-up frontiers again"));
    assert_eq!(machine.widen_search(1), Some("planning past obstacle cells"));
    assert_eq!(machine.widen_search(1), Some("looking again at the walls seen before"));
    machine.explorer = given_up_and_seen(&machine);
    assert_eq!(machine.widen_search(1), None, "after the second look at every wall");
}

#[test]
fn a_sample_set_aside_is_tried_again_at_once_when_the_search_for_samples_has_nothing_else_to_find() {
    let rock = (102.5, 100.5);
    let mut machine = machine_on(corridor());
    machine.set_rocks(vec![rock]);
    let fail_twice = |machine: &mut Machine| {
        for side in [-1.0, 1.0] {
            machine.samples.note_failed_approach(rock, machine.mission.frame, (102.5, 100.5 + side));
        }
    };
    fail_twice(&mut machine);
    machine.step(&Observation { samples_remaining: 1, ..observation(1, 100.5, 100.5) });
    let chased = |machine: &Machine, samples_remaining| {
        let obs = Observation { samples_remaining, ..observation(2, 100.5, 100.5) };
        machine.sample_to_chase(&obs, machine.params.sample_detour_cost).map(|chase| chase.at)
    };
    assert_eq!(chased(&machine, 1), None, "set aside while the rover explores the map");
    assert!(machine.widen_search(1).is_some());
    assert_eq!(chased(&machine, 1), Some(rock), "the search for samples cannot find another");
    assert_eq!(chased(&machine, 2), None, "another sample missing: the search may find it");
    fail_twice(&mut machine);
    assert_eq!(chased(&machine, 1), None, "four failures: it waits its time");
}

#[test]
fn at_the_deadline_the_rover_goes_home_without_detours_and_stops_there() {
    let (mut machine, late) = started_at_home_in_the_corridor();
    let mut sample_in_view = observation(late, 120.5, 100.5);
    sample_in_view.rock = Some(Sighting { bearing_rad: 0.0, distance_m: 3.0 });
    machine.step(&sample_in_view);
    assert_eq!(machine.status().mode, Mode::ReturnHome, "no detour for a sample at the deadline");
    assert_eq!(machine.status().target, Some((100.5, 100.5)));
    machine.step(&observation(late + 1, 101.0, 100.5));
    assert_eq!(machine.status().mode, Mode::Done);
    assert_eq!(machine.step(&observation(late + 2, 101.0, 100.5)).throttle, 0.0);
}

#[test]
fn an_approach_under_way_at_the_deadline_gives_way_to_the_way_home() {
    let (mut machine, late) = started_at_home_in_the_corridor();
    let mut sample_in_view = observation(late - 100, 105.5, 100.5);
    sample_in_view.rock = Some(Sighting { bearing_rad: 0.0, distance_m: 3.0 });
    machine.step(&sample_in_view);
    assert_eq!(machine.status().mode, Mode::ApproachSample, "4 s before the deadline, 2.4 s from home");
    sample_in_view.frame = late;
    machine.step(&sample_in_view);
    assert_eq!((machine.status().mode, machine.status().reason.as_str()), (Mode::ReturnHome, "mission deadline"));
}

#[test]
fn an_approach_that_leads_away_from_home_ends_when_the_way_back_would_miss_the_deadline() {
    let (mut machine, late) = started_at_home_in_the_corridor();
    let params = DecisionParams::default();
    let ten_s_before = late - params.frames(10.0);
    let mut sample_in_view = observation(ten_s_before, 120.5, 100.5);
    sample_in_view.rock = Some(Sighting { bearing_rad: 0.0, distance_m: 8.0 });
    machine.step(&sample_in_view);
    assert_eq!(machine.status().mode, Mode::ApproachSample, "20 m from home: 9.5 s at the return speed");
    machine.step(&observation(ten_s_before + 1, 126.5, 100.5));
    assert_eq!(
        (machine.status().mode, machine.status().reason.as_str()),
        (Mode::ReturnHome, "mission deadline"),
        "26 m from home: 12.4 s"
    );
}

/// A machine on the corridor map that has seen the rover at (100.5, 100.5).
fn machine_in_the_corridor(params: DecisionParams) -> Machine {
    let mut machine = machine_on_with(corridor(), params);
    machine.step(&observation(1, 100.5, 100.5));
    machine
}

#[test]
fn a_goal_off_the_map_or_on_a_mapped_obstacle_is_refused() {
    let mut machine = machine_in_the_corridor(DecisionParams { goal_seen_m: 5.0, ..DecisionParams::default() });
    assert_eq!(machine.navigate_to((-3.0, 100.0)), Err(GoalFailure::OutsideMap));
    assert_eq!(machine.navigate_to((100.5, 250.0)), Err(GoalFailure::OutsideMap));
    assert_eq!(machine.navigate_to((102.5, 104.5)), Err(GoalFailure::Occupied), "a wall of the corridor, close by");
    assert_eq!(machine.status().mode, Mode::Explore, "the mission goes on");
    assert_eq!(machine.navigate_to((110.5, 110.5)), Ok(()), "a wall far off: the map may be wrong there");
}

#[test]
fn a_navigation_drives_along_its_path_and_ends_at_the_goal_where_the_mission_goes_on() {
    let mut machine = machine_in_the_corridor(DecisionParams::default());
    machine.navigate_to((120.5, 100.5)).unwrap();
    let drive = machine.step(&observation(2, 100.5, 100.5));
    assert_eq!(machine.status().mode, Mode::Navigate);
    assert!(drive.throttle > 0.0, "drives toward the goal ahead: {drive:?}");
    assert_eq!(machine.status().target, Some((120.5, 100.5)));
    let progress = machine.navigation_progress().unwrap();
    assert!((19.0..21.5).contains(&progress.distance_remaining_m), "{progress:?}");
    assert!(!machine.path().is_empty());
    machine.step(&observation(3, 110.5, 100.5));
    let closer = machine.navigation_progress().unwrap().distance_remaining_m;
    assert!(closer < progress.distance_remaining_m - 9.0, "{closer}");
    let drive = machine.step(&observation(4, 120.2, 100.6));
    assert!(drive.brake > 0.0 && drive.throttle == 0.0, "{drive:?}");
    assert_eq!(machine.take_navigation_end(), Some(NavigationEnd::Reached));
    assert_eq!(machine.take_navigation_end(), None, "taken once");
    assert_eq!(machine.status().mode, Mode::Explore);
}

#[test]
fn a_goal_walled_off_on_the_map_is_tried_past_the_walls_and_given_up_when_stuck_there() {
    let mut data = vec![100i8; CELLS];
    for y in 98..103 {
        for x in 90..130 {
            data[cell_at(x, y)] = 0;
        }
    }
    data[cell_at(150, 100)] = 0;
    let params = DecisionParams { goal_max_recoveries: 0.0, ..DecisionParams::default() };
    let mut machine = machine_on_with(Grid::from_occupancy(&data).unwrap(), params.clone());
    machine.step(&observation(1, 100.5, 100.5));
    machine.navigate_to((150.5, 100.5)).unwrap();
    assert!(machine.step(&observation(2, 100.5, 100.5)).throttle > 0.0, "the map may be wrong: it tries");
    let stuck_frames = params.frames(params.stuck_s) + 2;
    for frame in 3..3 + stuck_frames {
        machine.step(&observation(frame, 100.5, 100.5));
    }
    assert_eq!(machine.take_navigation_end(), Some(NavigationEnd::Failed(GoalFailure::NoProgress)));
}

#[test]
fn a_goal_that_turns_out_inside_an_obstacle_is_given_up() {
    let mut machine = machine_in_the_corridor(DecisionParams::default());
    machine.navigate_to((135.5, 100.5)).unwrap();
    machine.step(&observation(2, 100.5, 100.5));
    assert_eq!(machine.status().mode, Mode::Navigate, "unknown ground may be free");
    let mut data = vec![100i8; CELLS];
    for y in 98..103 {
        for x in 90..140 {
            let rock = (134..=136).contains(&x) && (99..=101).contains(&y);
            data[cell_at(x, y)] = if x < 130 {
                0
            } else if rock {
                100
            } else {
                -1
            };
        }
    }
    machine.set_map(Grid::from_occupancy(&data).unwrap());
    machine.step(&observation(3, 101.5, 100.5));
    assert_eq!(machine.take_navigation_end(), None, "blocked on the map, seen from afar: the rover looks");
    machine.step(&observation(4, 132.5, 100.5));
    assert_eq!(machine.take_navigation_end(), Some(NavigationEnd::Failed(GoalFailure::Occupied)));
}

#[test]
fn a_canceled_navigation_brakes_and_gives_the_rover_back_to_the_mission() {
    let params = DecisionParams { start_mission: false, ..DecisionParams::default() };
    let mut machine = machine_in_the_corridor(params);
    assert_eq!(machine.status().mode, Mode::Idle);
    machine.navigate_to((120.5, 100.5)).unwrap();
    assert!(machine.step(&observation(2, 100.5, 100.5)).throttle > 0.0);
    assert!(machine.cancel_navigation());
    assert!(!machine.cancel_navigation(), "nothing left to cancel");
    let drive = machine.step(&observation(3, 101.5, 100.5));
    assert!(drive.brake > 0.0 && drive.throttle == 0.0, "{drive:?}");
    assert_eq!(machine.status().mode, Mode::Idle);
    assert_eq!(machine.take_navigation_end(), None, "a cancel is no end of the machine's own");
}

#[test]
fn the_mission_waits_for_its_start_and_holds_while_paused() {
    let params = DecisionParams { start_mission: false, ..DecisionParams::default() };
    let mut machine = machine_in_the_corridor(params);
    let drive = machine.step(&observation(2, 100.5, 100.5));
    assert!(drive.brake > 0.0 && drive.throttle == 0.0);
    assert!(machine.pause().is_ok());
    assert!(machine.pause().is_err(), "already paused");
    assert_eq!(machine.status().mode, Mode::Paused);
    assert!(machine.resume_after_pause().is_ok());
    assert!(machine.resume_after_pause().is_err(), "not paused");
    assert_eq!(machine.status().mode, Mode::Idle);
    assert_eq!(machine.start_mission(), Ok("mission started"));
    assert!(machine.start_mission().is_err());
    assert!(machine.step(&observation(3, 100.5, 100.5)).throttle > 0.0, "explores");
    assert_eq!(machine.status().mode, Mode::Explore);
    machine.pause().unwrap();
    let drive = machine.step(&observation(4, 100.5, 100.5));
    assert!(drive.brake > 0.0 && drive.throttle == 0.0);
    assert_eq!(machine.return_home_now(), Ok("returning home"));
    assert_eq!(machine.status().mode, Mode::ReturnHome, "a return home ends the pause");
    machine.step(&observation(5, 110.5, 100.5));
    assert_eq!(machine.status().mode, Mode::ReturnHome);
    let mut collecting = observation(6, 110.5, 100.5);
    collecting.picking_up = true;
    machine.step(&collecting);
    assert_eq!(machine.status().mode, Mode::Pickup, "a sample in the arm's reach is picked up");
    machine.step(&observation(7, 110.5, 100.5));
    machine.step(&observation(8, 110.5, 100.5));
    assert_eq!(machine.status().mode, Mode::ReturnHome, "then home again, not exploring");
}

#[test]
fn frames_held_still_from_outside_do_not_count_as_stuck() {
    let params = DecisionParams::default();
    let after_the_hold = 10 + params.frames(params.stuck_s.max(params.stall_s)) + 5;
    let stepped_over_a_hold = |held_still: bool| {
        let mut machine = machine_in_the_corridor(params.clone());
        for frame in 2..10 {
            assert!(machine.step(&observation(frame, 100.5, 100.5)).throttle > 0.0);
        }
        if held_still {
            machine.start_afresh();
        }
        machine.step(&observation(after_the_hold, 100.5, 100.5));
        machine.status().mode
    };
    assert_eq!(stepped_over_a_hold(false), Mode::Recover, "without the hold noted, the gap looks stuck");
    assert_eq!(stepped_over_a_hold(true), Mode::Explore);
}
