//! The bridge's side of a simulator in the same process, without a socket: each telemetry read as
//! the bridge reads it off the wire and numbered as the bridge numbers it, each command written as
//! the bridge writes its events, and two telemetries in flight as with the Unity client (one on
//! open, one on the Engine.IO open, then one per command). The in-process mission runs the graph's
//! libraries over it.

use std::collections::VecDeque;

use rover_msgs::msg::DriveCommand;
use serde_json::Value;

use crate::clock::SimClock;
use crate::convert::{FrameMessages, PinholeCamera};
use crate::node::BridgeParams;
use crate::reply::{DataEvent, DriveValues};
use crate::telemetry::{SimTelemetry, parse_telemetry};

/// Telemetry messages in flight between the Unity client and the bridge (unity-sim-spec 1.5), so
/// that each command is applied one step after the state it was decided on.
const LOOPS_IN_FLIGHT: usize = 2;

/// A simulator in the same process that speaks the Unity client's messages.
pub trait UnityPeer {
    /// The telemetry JSON object of its current state.
    fn telemetry_json(&mut self) -> String;
    /// Takes one event of the bridge, its name and JSON argument; whether it stepped (and so
    /// has a telemetry to send), as the Unity client answers only the commands it applies.
    fn receive(&mut self, event: &str, data: &Value) -> anyhow::Result<bool>;
}

/// A simulator linked to the graph's libraries as the bridge links it over the socket.
pub struct DirectLink<P> {
    peer: P,
    in_flight: VecDeque<SimTelemetry>,
    max_payload_bytes: usize,
    clock: SimClock,
    camera: PinholeCamera,
}

impl<P: UnityPeer> DirectLink<P> {
    /// Opens the link to a peer whose frames are `frame_period_s` apart: its first telemetries go
    /// in flight.
    pub fn open(peer: P, frame_period_s: f64) -> anyhow::Result<Self> {
        let mut link = DirectLink {
            peer,
            in_flight: VecDeque::with_capacity(LOOPS_IN_FLIGHT),
            max_payload_bytes: BridgeParams::default().max_payload_bytes as usize,
            clock: SimClock::new(frame_period_s, true),
            camera: PinholeCamera::rover(),
        };
        for _ in 0..LOOPS_IN_FLIGHT {
            link.read_telemetry()?;
        }
        Ok(link)
    }

    /// The simulator.
    pub fn peer(&self) -> &P {
        &self.peer
    }

    /// The messages of the next telemetry in flight, as the bridge publishes them for frame
    /// `frame`, stamped with its simulated time; none when every telemetry has been taken and no
    /// command sent since.
    pub fn next_frame(&mut self, frame: u64) -> Option<FrameMessages> {
        let telemetry = self.in_flight.pop_front()?;
        Some(FrameMessages::new(&telemetry, frame, self.clock.stamp_frame(frame), &self.camera))
    }

    /// Answers the frame as the bridge does with what the graph wrote for it: a pickup when one
    /// was requested, else the drive command, else (none came) the brake `brake`.
    pub fn answer(&mut self, pickup_requested: bool, drive: Option<&DriveCommand>, brake: f32) -> anyhow::Result<()> {
        if pickup_requested {
            return self.send_pickup();
        }
        match drive {
            Some(command) => self.send_drive(command, brake),
            None => self.send_drive(&DriveCommand { brake, ..DriveCommand::default() }, brake),
        }
    }

    /// Sends a drive command as the bridge answers with one: clamped, as the text of a `data`
    /// event. A command the bridge refuses (not finite) is a brake of `refused_brake` here: one
    /// thread has no last command to hold.
    fn send_drive(&mut self, command: &DriveCommand, refused_brake: f32) -> anyhow::Result<()> {
        let values = DriveValues::checked(command.throttle, command.brake, command.steering_angle_deg)
            .unwrap_or_else(|_| DriveValues::brake(refused_brake));
        self.send("data", serde_json::to_value(DataEvent::new(values, "", ""))?)
    }

    /// Sends a pickup, as the bridge does for a pending `rover/pickup`.
    fn send_pickup(&mut self) -> anyhow::Result<()> {
        self.send("pickup", Value::Object(serde_json::Map::new()))
    }

    fn send(&mut self, event: &str, data: Value) -> anyhow::Result<()> {
        if !self.peer.receive(event, &data)? {
            anyhow::bail!("the simulator ignored the {event} event");
        }
        self.read_telemetry()
    }

    /// Reads the peer's telemetry as the bridge parses it, refused beyond its payload limit.
    fn read_telemetry(&mut self) -> anyhow::Result<()> {
        let telemetry = parse_telemetry(&self.peer.telemetry_json(), self.max_payload_bytes)?
            .ok_or_else(|| anyhow::anyhow!("the simulator sent empty telemetry"))?;
        self.in_flight.push_back(telemetry);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::std_msgs::Header;

    use super::*;

    /// A peer that answers with telemetry numbered by the events it got, and keeps the events.
    #[derive(Default)]
    struct Recorder {
        events: Vec<(String, Value)>,
    }

    impl UnityPeer for Recorder {
        fn telemetry_json(&mut self) -> String {
            let x = 100.0 + self.events.len() as f64;
            format!(
                r#"{{"steering_angle":"0","throttle":"0","brake":"0","speed":"0","position":"{x};50","pitch":"0","yaw":"90","roll":"0","near_sample":"0","picking_up":"0","sample_count":"6","samples_x":"1","samples_y":"2","image":"/9j/4AAQ"}}"#
            )
        }

        fn receive(&mut self, event: &str, data: &Value) -> anyhow::Result<bool> {
            self.events.push((event.to_string(), data.clone()));
            Ok(event != "ignored")
        }
    }

    fn field<'a>(event: &'a (String, Value), name: &str) -> &'a str {
        event.1[name].as_str().expect("a string value")
    }

    #[test]
    fn frames_are_stamped_with_their_simulated_time() {
        let mut link = DirectLink::open(Recorder::default(), 0.04).unwrap();
        let frame = link.next_frame(50).unwrap();
        assert_eq!(frame.telemetry.header.stamp, rover_msgs::builtin_interfaces::Time { sec: 2, nanosec: 0 });
        assert_eq!(frame.compressed.header.stamp, frame.telemetry.header.stamp, "paired by stamp");
        assert!(frame.compressed.data.starts_with(&[0xff, 0xd8]), "the simulator's JPEG");
    }

    fn drive(throttle: f32, brake: f32, steering_angle_deg: f32) -> DriveCommand {
        DriveCommand { header: Header::default(), frame: 1, throttle, brake, steering_angle_deg }
    }

    #[test]
    fn each_command_is_applied_two_frames_after_the_state_it_answers() {
        let mut link = DirectLink::open(Recorder::default(), 0.04).unwrap();
        let first = link.next_frame(1).unwrap();
        assert_eq!((first.telemetry.frame, first.telemetry.x_m), (1, 100.0));
        link.send_drive(&drive(0.3, 0.0, 5.0), 10.0).unwrap();
        assert_eq!(link.next_frame(2).unwrap().telemetry.x_m, 100.0, "the second telemetry of the open");
        link.send_pickup().unwrap();
        assert_eq!(link.next_frame(3).unwrap().telemetry.x_m, 101.0, "the state after the first command");
        assert_eq!(link.peer().events[1], ("pickup".to_string(), Value::Object(serde_json::Map::new())));
        assert_eq!(link.next_frame(4).unwrap().telemetry.x_m, 102.0);
        assert!(link.next_frame(5).is_none(), "nothing in flight until the next command");
    }

    #[test]
    fn an_event_the_simulator_ignores_is_an_error_not_a_lost_loop() {
        let mut link = DirectLink::open(Recorder::default(), 0.04).unwrap();
        let error = link.send("ignored", Value::Null).unwrap_err();
        assert!(error.to_string().contains("ignored the ignored event"), "{error}");
    }

    #[test]
    fn a_drive_is_sent_as_the_bridge_sends_it() {
        let mut link = DirectLink::open(Recorder::default(), 0.04).unwrap();
        link.send_drive(&drive(0.3, 0.713_479_546_953_064_8_f64 as f32, 5.0), 10.0).unwrap();
        link.send_drive(&drive(2.0, -1.0, -40.0), 10.0).unwrap();
        link.send_drive(&drive(f32::NAN, 0.0, 0.0), 10.0).unwrap();
        let events = &link.peer().events;
        assert!(events.iter().all(|(name, _)| name == "data"));
        assert_eq!(field(&events[0], "brake"), "0.7134795", "the shortest text of the f32");
        assert_eq!((field(&events[0], "throttle"), field(&events[0], "steering_angle")), ("0.3", "5"));
        let clamped = (field(&events[1], "throttle"), field(&events[1], "brake"), field(&events[1], "steering_angle"));
        assert_eq!(clamped, ("1", "0", "-15"));
        assert_eq!((field(&events[2], "throttle"), field(&events[2], "brake")), ("0", "10"), "refused: a brake");
    }

    #[test]
    fn a_frame_is_answered_with_the_pickup_first_else_the_drive_else_the_brake() {
        let mut link = DirectLink::open(Recorder::default(), 0.04).unwrap();
        link.answer(true, Some(&drive(0.3, 0.0, 5.0)), 10.0).unwrap();
        link.answer(false, Some(&drive(0.3, 0.0, 5.0)), 10.0).unwrap();
        link.answer(false, None, 10.0).unwrap();
        let events = &link.peer().events;
        assert_eq!(events[0].0, "pickup");
        assert_eq!((events[1].0.as_str(), field(&events[1], "throttle")), ("data", "0.3"));
        assert_eq!((field(&events[2], "throttle"), field(&events[2], "brake")), ("0", "10"));
    }
}
