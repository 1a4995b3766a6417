//! The coordinate frames of the graph's messages (REP 103 and REP 105), named once.

/// Frame of the world map (the mapping node's `map`).
pub const MAP: &str = "map";
/// Frame of the odometry origin (the same place as the map's: the simulator's world frame).
pub const ODOM: &str = "odom";
/// Frame of the rover body, on the floor below its reported position.
pub const BASE_LINK: &str = "base_link";
/// Frame of the camera body (REP 103: x forward, y left, z up).
pub const CAMERA_LINK: &str = "camera_link";
/// Optical frame of the camera (REP 103: z forward, x right, y down).
pub const CAMERA_OPTICAL: &str = "camera_optical_frame";
