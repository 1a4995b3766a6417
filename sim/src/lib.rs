//! The headless rover simulator: a stand-in for the Unity "Search and Sample Return" simulator
//! that speaks its client's exact Socket.IO dialect ([`wire`]).

pub mod wire;
