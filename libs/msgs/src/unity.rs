//! What the Unity simulator reports of the rover, in its own units and angle ranges: the values
//! that its telemetry event, the recorded `robot_log.csv` and the headless simulator share.

/// Simulated time from one telemetry frame to the next: the headless simulator's step, and what
/// the nodes take a frame to last unless told otherwise, seconds.
pub const FRAME_PERIOD_S: f64 = 0.04;

/// The rover's controls and pose as Unity reports them each frame (unity-sim-spec 2).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReportedState {
    /// Steering angle applied, degrees, positive left.
    pub steering_angle_deg: f64,
    /// Last accepted throttle.
    pub throttle: f64,
    /// Last accepted brake.
    pub brake: f64,
    /// Signed speed, m/s.
    pub speed_mps: f64,
    /// Position x, metres.
    pub x_m: f64,
    /// Position y (Unity z), metres.
    pub y_m: f64,
    /// Pitch, degrees in [0, 360), positive nose down.
    pub pitch_deg: f64,
    /// Yaw, degrees counter-clockwise from +x, in [0, 360).
    pub yaw_deg: f64,
    /// Roll, degrees in [0, 360), positive with the right side up.
    pub roll_deg: f64,
}
