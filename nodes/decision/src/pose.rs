//! Where the rover is: its position and heading in the world frame, and the angles between it and
//! a point.

/// Where the rover is, in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position {
    /// Metres.
    pub x_m: f64,
    /// Metres.
    pub y_m: f64,
    /// Heading, radians counter-clockwise from +x.
    pub yaw_rad: f64,
}

impl Position {
    /// Distance to (x, y), metres.
    pub fn distance_to(&self, (x_m, y_m): (f64, f64)) -> f64 {
        (x_m - self.x_m).hypot(y_m - self.y_m)
    }

    /// Bearing of (x, y) relative to the heading, radians in (-pi, pi], positive left.
    pub fn bearing_to(&self, (x_m, y_m): (f64, f64)) -> f64 {
        wrap_rad((y_m - self.y_m).atan2(x_m - self.x_m) - self.yaw_rad)
    }

    /// The world point `distance_m` away at `bearing_rad` from the heading.
    pub fn point_at(&self, bearing_rad: f64, distance_m: f64) -> (f64, f64) {
        let (s, c) = (self.yaw_rad + bearing_rad).sin_cos();
        (self.x_m + distance_m * c, self.y_m + distance_m * s)
    }
}

/// Where a rover that went from `before` to `at` in one frame will be a frame later if it keeps
/// going alike, (x, y) metres.
pub(crate) fn one_frame_on(before: &Position, at: &Position) -> (f64, f64) {
    (2.0 * at.x_m - before.x_m, 2.0 * at.y_m - before.y_m)
}

/// An angle wrapped to (-pi, pi].
pub(crate) fn wrap_rad(angle_rad: f64) -> f64 {
    let wrapped = angle_rad.rem_euclid(std::f64::consts::TAU);
    if wrapped > std::f64::consts::PI { wrapped - std::f64::consts::TAU } else { wrapped }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_and_bearings() {
        assert!((wrap_rad(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        let p = Position { x_m: 1.0, y_m: 1.0, yaw_rad: std::f64::consts::FRAC_PI_2 };
        assert!(
            (p.bearing_to((0.0, 1.0)) - std::f64::consts::FRAC_PI_2).abs() < 1e-12,
            "west is left when facing north"
        );
        let (x, y) = p.point_at(0.0, 2.0);
        assert!((x - 1.0).abs() < 1e-12 && (y - 3.0).abs() < 1e-12);
    }
}
