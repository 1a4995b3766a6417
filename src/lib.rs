//! The `rover` application: the subcommands that combine the libraries of the graph (replaying
//! recorded datasets, the demo, the evaluation, recording and playing bags).

pub mod bag;
pub mod chaos;
pub mod cpu;
pub mod dataset;
pub mod demo;
pub mod eval;
pub mod graph;
pub mod graph_mission;
pub mod link;
pub mod live_view;
pub mod mission;
pub mod mission_map;
pub mod nodes;
pub mod replay;
pub mod replay_dds;
pub mod sim_check;
pub mod steadiness;
pub mod time_by_mode;
pub mod timeline;
