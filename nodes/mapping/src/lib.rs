//! World mapping of the rover: terrain scans projected into a 200 m x 200 m evidence grid
//! ([`map`]) with pitch and roll corrected through the camera model ([`projection`]), the exact
//! Udacity scores ([`score`]), the map inset image ([`image`]), the located rocks ([`rocks`]), the
//! snapshot that a restarted node carries on from ([`snapshot`]) and what the node does with each
//! message ([`mapper`]), which the in-process mission runs too.

mod image;
pub mod map;
mod mapper;
mod markers;
pub mod node;
pub mod params;
pub mod projection;
mod rocks;
pub mod score;
mod snapshot;
