//! The located rocks and the places of the collected samples as markers, which RViz and Foxglove
//! draw over the map: a yellow sphere for each rock located and not collected, a green one for
//! each sample collected. Each publication replaces the last one whole.

use rover_msgs::geometry_msgs::{Point, Pose, Quaternion, Vector3};
use rover_msgs::std_msgs::{ColorRGBA, Header};
use rover_msgs::visualization_msgs::{Marker, MarkerArray};

/// Diameter of a sphere, metres: larger than a sample, to be seen on the whole map.
const SPHERE_M: f64 = 1.0;
/// A located rock's colour.
const LOCATED: ColorRGBA = ColorRGBA { r: 1.0, g: 0.85, b: 0.0, a: 1.0 };
/// A collected sample's colour.
const COLLECTED: ColorRGBA = ColorRGBA { r: 0.1, g: 0.8, b: 0.2, a: 1.0 };

/// The markers of `rocks` (located) and `collected` (world metres) in the frame of `header`,
/// after one that deletes the markers published before.
pub(crate) fn sample_markers(header: &Header, rocks: &[(f64, f64)], collected: &[(f64, f64)]) -> MarkerArray {
    let delete_earlier = Marker { header: header.clone(), action: Marker::DELETEALL, ..Marker::default() };
    let located = spheres(header, "located", rocks, LOCATED);
    let picked = spheres(header, "collected", collected, COLLECTED);
    MarkerArray { markers: std::iter::once(delete_earlier).chain(located).chain(picked).collect() }
}

fn spheres<'a>(
    header: &'a Header,
    ns: &'a str,
    places: &'a [(f64, f64)],
    color: ColorRGBA,
) -> impl Iterator<Item = Marker> + 'a {
    places.iter().zip(0..).map(move |(&(x, y), id)| Marker {
        header: header.clone(),
        ns: ns.to_string(),
        id,
        r#type: Marker::SPHERE,
        action: Marker::ADD,
        pose: Pose { position: Point { x, y, z: SPHERE_M / 2.0 }, orientation: Quaternion::IDENTITY },
        scale: Vector3 { x: SPHERE_M, y: SPHERE_M, z: SPHERE_M },
        color: color.clone(),
        ..Marker::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rocks_and_collected_samples_are_spheres_of_their_own_namespace_after_a_delete_all() {
        let header = Header::now("map");
        let markers = sample_markers(&header, &[(97.5, 74.5), (122.0, 51.5)], &[(60.0, 100.0)]).markers;
        assert_eq!(markers[0].action, Marker::DELETEALL);
        let shown: Vec<(&str, i32, f64, f64)> =
            markers[1..].iter().map(|m| (m.ns.as_str(), m.id, m.pose.position.x, m.pose.position.y)).collect();
        assert_eq!(shown, [("located", 0, 97.5, 74.5), ("located", 1, 122.0, 51.5), ("collected", 0, 60.0, 100.0)]);
        for marker in &markers[1..] {
            assert_eq!(
                (marker.r#type, marker.action, marker.header.frame_id.as_str()),
                (Marker::SPHERE, Marker::ADD, "map")
            );
            assert_eq!(marker.pose.orientation, Quaternion::IDENTITY, "a valid orientation");
            assert!(marker.scale.x > 0.0 && marker.color.a == 1.0);
        }
        assert_ne!(markers[1].color, markers[3].color);
    }
}
