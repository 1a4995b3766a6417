//! Tools around the graph: recorded datasets read as the simulator wrote them, replayed through
//! perception and mapping, compared with the simulator (`rover sim-check`), rosbag2 bags, and the
//! Foxglove live view; and the firewall rules that keep other hosts' DDS packets out.

pub mod bag;
pub mod dataset;
pub mod dds_firewall;
pub mod live_view;
pub mod replay;
mod replay_dds;
pub mod sim_check;
