//! Fuzz targets for messages from DDS: any TerrainScan, Telemetry or OccupancyGrid (NaN,
//! infinities, huge grid sizes, zero cell sizes) goes through `rover_msgs::validate`, and one that
//! passes through the mapping library's `WorldMap::update` and the decision library's observation
//! and step, without a panic; the strategies bound the cell arrays, so no input takes long.

use proptest::prelude::*;
use rover_decision::grid::Grid;
use rover_decision::local::FreeSpaceRays;
use rover_decision::machine::Machine;
use rover_decision::params::DecisionParams;
use rover_fuzzing::messages::{occupancy_grid, telemetry, terrain_scan};
use rover_mapping::map::{MapConfig, ScanGrid, Update, WorldMap};
use rover_mapping::projection::Pose;
use rover_msgs::msg::TerrainScan;
use rover_msgs::validate::Validate;

/// A decision machine with the default parameters.
fn machine() -> Machine {
    Machine::new(DecisionParams::default())
}

/// A valid scan that sees nothing (the default one has cells of 0 m, which the nodes reject).
fn empty_scan() -> TerrainScan {
    TerrainScan { resolution_m: 0.1, ..TerrainScan::default() }
}

/// Runs one decision step on a valid scan; the drive it gives is finite.
fn decide(machine: &mut Machine, scan: &TerrainScan) -> Result<(), TestCaseError> {
    let mut rays = FreeSpaceRays::for_decision(0.6);
    let drive = machine.step(&rover_decision::observation(scan, &mut rays));
    prop_assert!([drive.throttle, drive.brake, drive.steering_deg].iter().all(|v| v.is_finite()), "{drive:?}");
    Ok(())
}

proptest! {
    #[test]
    fn fuzz_messages_terrain_scan_into_map(scan in terrain_scan()) {
        if scan.validate().is_ok() {
            let mut map = WorldMap::new(MapConfig::default());
            if let Update::Used(cells) = map.update(&ScanGrid::of(&scan), Pose::of_scan(&scan)) {
                prop_assert!(cells <= scan.cells.len());
            }
            prop_assert!(map.occupancy().iter().all(|&v| v == -1 || (0..=100).contains(&v)));
        }
    }

    #[test]
    fn fuzz_messages_scan_into_decision(scan in terrain_scan()) {
        if scan.validate().is_ok() {
            decide(&mut machine(), &scan)?;
        }
    }

    #[test]
    fn fuzz_messages_occupancy_grid_into_decision(grid in occupancy_grid(), telemetry in telemetry()) {
        if grid.validate().is_ok() && telemetry.validate().is_ok() {
            let mut machine = machine();
            if let Some(grid) = Grid::from_occupancy(&grid.data) {
                machine.set_map(grid);
            }
            decide(&mut machine, &TerrainScan { telemetry, ..empty_scan() })?;
        }
    }
}
