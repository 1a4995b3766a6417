//! The graph's cores in one thread, without DDS: a message published into the [`Executor`] reaches
//! every core that reads its topic, in the order of the graph table, and what they write travels
//! on the same way until nothing is left. It runs the same [`NodeCore`]s as the DDS adapter,
//! deterministically, for the fast in-process missions.

use std::any::Any;
use std::collections::VecDeque;

use rover_msgs::RosMessage;
use rover_msgs::builtin_interfaces::Time;

use crate::adapter::check_inputs_are_the_tables;
use crate::graph::{GRAPH, node_topics};
use crate::node_core::{FromParams, Inputs, NodeCore, Outbox, Sent};
use crate::topics::{Topic, all_names};

/// A core as the executor drives it, whatever its type.
trait Running {
    fn name(&self) -> &'static str;
    fn reads(&self, topic: &str) -> bool;
    /// Hands `message` of `topic` to the core, if it reads that topic.
    fn deliver(&mut self, topic: &str, message: &dyn Any, out: &mut Outbox);
    fn start(&mut self, out: &mut Outbox);
    fn stop(&mut self, out: &mut Outbox);
}

struct RunningCore<C> {
    core: C,
    inputs: Inputs<C>,
}

impl<C: NodeCore> Running for RunningCore<C> {
    fn name(&self) -> &'static str {
        C::NAME
    }

    fn reads(&self, topic: &str) -> bool {
        self.inputs.ports.find(topic).is_some()
    }

    fn deliver(&mut self, topic: &str, message: &dyn Any, out: &mut Outbox) {
        if let Some(port) = self.inputs.ports.find(topic) {
            port.deliver(&mut self.core, message, out);
        }
    }

    fn start(&mut self, out: &mut Outbox) {
        self.core.start(out);
    }

    fn stop(&mut self, out: &mut Outbox) {
        self.core.stop(out);
    }
}

/// Cores of the graph run in one thread, in the graph table's order.
pub struct Executor {
    cores: Vec<Box<dyn Running>>,
    watched: Vec<&'static str>,
    out: Outbox,
}

impl Executor {
    /// An executor with no core yet; its caller reads the topics `watched` in what
    /// [`Executor::publish`] returns (the other topics no core reads are not built at all).
    pub fn new(watched: &[&'static str]) -> Self {
        Executor { cores: Vec::new(), watched: watched.to_vec(), out: Outbox::new(Time::default(), Vec::new()) }
    }

    /// Adds the core `C`, configured by `params`; cores are kept in the graph table's order.
    pub fn add<C: FromParams>(&mut self, params: C::Params) -> anyhow::Result<()> {
        let inputs = C::inputs();
        check_inputs_are_the_tables::<C>(&inputs.ports.names())?;
        let core = C::new(params)?;
        self.cores.push(Box::new(RunningCore { core, inputs }));
        let position = |name: &str| GRAPH.iter().position(|entry| entry.node == name);
        self.cores.sort_by_key(|core| position(core.name()));
        Ok(())
    }

    /// Starts every core at time `now`; returns what they wrote, and what that made the others write.
    pub fn start(&mut self, now: Time) -> Vec<Sent> {
        let read = |topic: &str| self.watched.contains(&topic) || self.cores.iter().any(|core| core.reads(topic));
        let unread = all_names().into_iter().filter(|topic| !read(topic)).collect();
        self.out = Outbox::new(now, unread);
        self.on_every_core(|core, out| core.start(out))
    }

    /// Publishes `message` on `topic` at time `now` into the graph and runs every core it reaches
    /// until nothing is left; returns everything the cores wrote, in order.
    pub fn publish<M: RosMessage>(&mut self, topic: &Topic<M>, message: M, now: Time) -> Vec<Sent> {
        self.out.set_now(now);
        let input = Sent::new(topic.name, Box::new(message));
        let mut written = self.run(VecDeque::from([input]));
        written.remove(0);
        written
    }

    /// Stops every core; returns what they wrote.
    pub fn stop(&mut self) -> Vec<Sent> {
        self.on_every_core(|core, out| core.stop(out))
    }

    /// Runs `act` on every core in order, then delivers what they wrote and what that leads to;
    /// returns it all.
    fn on_every_core(&mut self, act: impl Fn(&mut dyn Running, &mut Outbox)) -> Vec<Sent> {
        let mut written = VecDeque::new();
        for core in &mut self.cores {
            act(core.as_mut(), &mut self.out);
            written.extend(checked_writes(core.name(), self.out.take()));
        }
        self.run(written)
    }

    /// Delivers the queued messages and everything they lead to; returns them all, in order.
    fn run(&mut self, mut queue: VecDeque<Sent>) -> Vec<Sent> {
        let mut delivered = Vec::new();
        while let Some(sent) = queue.pop_front() {
            for core in &mut self.cores {
                core.deliver(sent.topic, sent.message(), &mut self.out);
                queue.extend(checked_writes(core.name(), self.out.take()));
            }
            delivered.push(sent);
        }
        delivered
    }
}

/// The messages of `written` that node `name` may write by the graph table; the others are
/// logged and dropped, as the DDS adapter has no publisher for them.
fn checked_writes(name: &'static str, written: Vec<Sent>) -> impl Iterator<Item = Sent> {
    let writes = node_topics(name).map_or(&[][..], |entry| entry.writes);
    written.into_iter().filter(move |sent| {
        let allowed = writes.contains(&sent.topic);
        if !allowed {
            tracing::error!("dropped a message on {}: the graph table does not let {name} write it", sent.topic);
        }
        allowed
    })
}

#[cfg(test)]
mod tests {
    use rover_msgs::msg::{DriveCommand, PickupRequest, Telemetry, TerrainScan};
    use rover_msgs::sensor_msgs::{CompressedImage, Image};
    use rover_msgs::std_msgs::Header;

    use super::*;
    use crate::NoParams;

    /// Reads the camera and telemetry as perception does; a scan for each camera frame, and the
    /// view when anyone wants it.
    struct Eyes;

    impl NodeCore for Eyes {
        type Params = NoParams;
        const NAME: &'static str = "perception";

        fn inputs() -> Inputs<Self> {
            Inputs::new()
                .on(&crate::topics::CAMERA_COMPRESSED, Self::on_camera)
                .on(&crate::topics::TELEMETRY, |_, _, _| {})
        }

        fn set_params(&mut self, _: NoParams) {}
    }

    impl FromParams for Eyes {
        fn new(_: NoParams) -> anyhow::Result<Self> {
            Ok(Eyes)
        }
    }

    impl Eyes {
        fn on_camera(&mut self, image: &CompressedImage, out: &mut Outbox) {
            out.publish(
                &crate::topics::TERRAIN,
                TerrainScan { header: image.header.clone(), ..TerrainScan::default() },
            );
            if out.wanted(&crate::topics::VISION) {
                out.publish(&crate::topics::VISION, Image::default());
            }
        }
    }

    /// Answers each scan with a drive command stamped like it, and (against the table) a pickup.
    struct Driver {
        maps: usize,
    }

    impl NodeCore for Driver {
        type Params = NoParams;
        const NAME: &'static str = "decision";

        fn inputs() -> Inputs<Self> {
            Inputs::new()
                .on(&crate::topics::TERRAIN, Self::on_scan)
                .on(&crate::topics::MAP, |driver, _, _| driver.maps += 1)
                .on(&crate::topics::ROCKS, |_, _, _| {})
                .on(&crate::topics::MAP_STATS, |_, _, _| {})
                .on(&crate::topics::GOAL_POSE, |_, _, _| {})
        }

        fn set_params(&mut self, _: NoParams) {}
    }

    impl FromParams for Driver {
        fn new(_: NoParams) -> anyhow::Result<Self> {
            Ok(Driver { maps: 0 })
        }
    }

    impl Driver {
        fn on_scan(&mut self, scan: &TerrainScan, out: &mut Outbox) {
            out.publish(
                &crate::topics::DRIVE_CMD,
                DriveCommand { header: scan.header.clone(), ..DriveCommand::default() },
            );
            out.publish(&crate::topics::PICKUP, PickupRequest::default());
        }
    }

    /// Reads what the table says pickup does not.
    struct Stray;

    impl NodeCore for Stray {
        type Params = NoParams;
        const NAME: &'static str = "pickup";

        fn inputs() -> Inputs<Self> {
            Inputs::new().on(&crate::topics::TERRAIN, |_, _, _| {})
        }

        fn set_params(&mut self, _: NoParams) {}
    }

    impl FromParams for Stray {
        fn new(_: NoParams) -> anyhow::Result<Self> {
            Ok(Stray)
        }
    }

    fn stamped(sec: i32) -> Header {
        Header::at("camera_optical_frame", Time { sec, nanosec: 0 })
    }

    fn topics_of(written: &[Sent]) -> Vec<&'static str> {
        written.iter().map(|sent| sent.topic).collect()
    }

    #[test]
    fn a_message_travels_through_every_core_that_reads_it_in_the_tables_order() {
        let mut graph = Executor::new(&[]);
        graph.add::<Driver>(NoParams {}).unwrap();
        graph.add::<Eyes>(NoParams {}).unwrap();
        assert!(graph.start(Time::default()).is_empty());
        let camera = CompressedImage { header: stamped(7), ..CompressedImage::default() };
        let written = graph.publish(&crate::topics::CAMERA_COMPRESSED, camera, Time::default());
        assert_eq!(topics_of(&written), ["rover/terrain", "rover/drive_cmd"], "no view nobody reads, no stray pickup");
        let command = written[1].on(&crate::topics::DRIVE_CMD).expect("a drive command");
        assert_eq!(command.header.stamp.sec, 7, "the scan's stamp, carried through");
        assert!(written[0].on(&crate::topics::DRIVE_CMD).is_none(), "a scan is not a drive command");
        let telemetry = graph.publish(&crate::topics::TELEMETRY, Telemetry::default(), Time::default());
        assert!(telemetry.is_empty());
    }

    #[test]
    fn a_watched_topic_is_built_and_returned() {
        let mut graph = Executor::new(&[crate::topics::VISION.name]);
        graph.add::<Eyes>(NoParams {}).unwrap();
        graph.start(Time::default());
        let written = graph.publish(&crate::topics::CAMERA_COMPRESSED, CompressedImage::default(), Time::default());
        assert_eq!(topics_of(&written), ["rover/terrain", "rover/vision"]);
    }

    #[test]
    fn a_core_whose_inputs_are_not_the_tables_is_refused() {
        let error = Executor::new(&[]).add::<Stray>(NoParams {}).unwrap_err().to_string();
        assert!(error.contains("node pickup handles [\"rover/terrain\"]"), "{error}");
        assert!(error.contains("libs/runtime/src/graph.rs") && error.contains("rover/telemetry"), "{error}");
    }
}
