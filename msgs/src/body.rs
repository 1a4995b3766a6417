//! The rover's body as the nodes assume it (unity-sim-spec 4): where the camera sits, how far the
//! arm reaches, and how far the rock evidence of one sample spreads. The one definition of these
//! facts for every node that needs them; the simulator keeps its own model of the true rover.

/// The camera's mounting on the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMount {
    /// Camera ahead of the reported position, metres.
    pub forward_m: f64,
    /// Camera above the body origin, metres.
    pub above_origin_m: f64,
    /// Body origin below the floor, metres.
    pub origin_below_floor_m: f64,
}

impl CameraMount {
    /// The Unity rover's camera: 0.4287 m ahead of the position and 0.2391 m above the body
    /// origin, which rests 0.0247 m below the floor (so 0.2144 m above level ground).
    pub const UNITY: CameraMount =
        CameraMount { forward_m: 0.4287, above_origin_m: 0.2391, origin_below_floor_m: 0.0247 };
}

impl Default for CameraMount {
    fn default() -> Self {
        CameraMount::UNITY
    }
}

/// The arm reaches this far ahead of the rover's position, metres.
pub const ARM_REACH_M: f64 = 0.84;

/// The rock evidence of one sample spreads this far, metres: a sample seen from afar projects up
/// to 3 m beyond where it lies, and no two sample places of the Unity world are closer than 7 m.
/// Rocks this close are one sample, and a pickup clears the rock evidence this close to the arm.
pub const SAMPLE_SPREAD_M: f64 = 4.0;
