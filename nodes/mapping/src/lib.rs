//! World mapping of the rover: terrain scans projected into a 200 m x 200 m evidence grid
//! ([`map`]) with pitch and roll corrected through the camera model ([`projection`]), the exact
//! Udacity scores ([`score`]), the map inset image ([`image`]), the located rocks ([`rocks`]) and
//! the snapshot that a restarted node carries on from ([`snapshot`]).

pub mod image;
pub mod map;
pub mod node;
pub mod params;
pub mod projection;
pub mod rocks;
pub mod score;
pub mod snapshot;
