//! The two inset images of the simulator's screen, and which of them a reply needs to carry.
//!
//! The simulator loads an inset only from a non-empty `inset_image1`/`inset_image2` and keeps
//! showing the last one it loaded otherwise (unity-sim-spec: `data`, the insets are display only;
//! the Unity client's `CommandServer.cs` makes a texture only from non-empty image bytes). So a
//! reply carries an inset only when the connection has not been sent that image yet: after it
//! changed, and in the first reply of a new connection. The other replies are about a hundred
//! bytes instead of several kilobytes, for the bridge to write and for the simulator to read and
//! decode.

use std::sync::{Arc, Mutex};

use rover_runtime::sync::lock;

/// The two inset images, as base64 JPEG (empty before the first, or in a reply, where the
/// connection has the image already).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Insets {
    /// World map (`inset_image1`).
    pub map: Arc<str>,
    /// Vision (`inset_image2`).
    pub vision: Arc<str>,
}

/// The insets last sent, and to which connection (`C` identifies one).
#[derive(Debug)]
pub(crate) struct InsetsSent<C> {
    last: Mutex<Option<(C, Insets)>>,
}

impl<C> Default for InsetsSent<C> {
    fn default() -> Self {
        InsetsSent { last: Mutex::new(None) }
    }
}

impl<C: PartialEq + Copy> InsetsSent<C> {
    /// The insets of the next reply on `connection` when the insets are `current`, noted as sent:
    /// each image that this connection was not the last to be sent, else empty. Call in the order
    /// the replies are sent.
    pub(crate) fn next_reply(&self, connection: C, current: &Insets) -> Insets {
        let mut last = lock(&self.last);
        let sent_here = last.as_ref().filter(|(to, _)| *to == connection).map(|(_, insets)| insets);
        let field = |now: &Arc<str>, sent: Option<&Arc<str>>| {
            if sent.is_some_and(|sent| Arc::ptr_eq(sent, now)) { Arc::from("") } else { now.clone() }
        };
        let reply = Insets {
            map: field(&current.map, sent_here.map(|insets| &insets.map)),
            vision: field(&current.vision, sent_here.map(|insets| &insets.vision)),
        };
        *last = Some((connection, current.clone()));
        reply
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn insets(map: &str, vision: &str) -> Insets {
        Insets { map: map.into(), vision: vision.into() }
    }

    #[test]
    fn an_inset_goes_out_once_per_image_and_connection() {
        let sent = InsetsSent::default();
        let first = insets("map-1", "vision-1");
        assert_eq!(sent.next_reply(1, &first), insets("map-1", "vision-1"));
        assert_eq!(sent.next_reply(1, &first), insets("", ""), "nothing new: both empty");
        let new_vision = Insets { vision: "vision-2".into(), ..first.clone() };
        assert_eq!(sent.next_reply(1, &new_vision), insets("", "vision-2"));
        assert_eq!(sent.next_reply(1, &new_vision), insets("", ""));
        assert_eq!(sent.next_reply(2, &new_vision), insets("map-1", "vision-2"), "a new connection gets both");
        assert_eq!(sent.next_reply(2, &new_vision), insets("", ""));
    }

    #[test]
    fn an_image_published_again_with_the_same_bytes_goes_out_again() {
        let sent = InsetsSent::default();
        assert_eq!(sent.next_reply(7, &insets("map", "vision")), insets("map", "vision"));
        assert_eq!(sent.next_reply(7, &insets("map", "vision")), insets("map", "vision"), "new images, same text");
    }
}
