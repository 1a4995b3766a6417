//! The `package.xml` files that make the crates ROS 2 packages (format 3, `ament_cargo`, built by
//! colcon-ros-cargo) agree with the Cargo manifests: same name, version and licence. The root
//! package compiles the node crates from their paths, so it declares no build dependency on their
//! packages (colcon would build each of them again, in a target folder of its own, first).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The crates that are ROS packages: the root `rover` and the node crates.
const ROS_CRATES: [&str; 7] =
    ["rover", "rover_bridge", "rover_perception", "rover_mapping", "rover_decision", "rover_pickup", "rover_sim"];

/// `cargo metadata` of the workspace, without dependencies.
fn metadata() -> serde_json::Value {
    let output = std::process::Command::new(env!("CARGO"))
        .args(["metadata", "--no-deps", "--format-version", "1", "--manifest-path"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml"))
        .output()
        .expect("run cargo metadata");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).expect("cargo metadata prints JSON")
}

/// The text of every element `<tag>...</tag>` of `xml`, in order.
fn elements(xml: &str, tag: &str) -> Vec<String> {
    let (open, close) = (format!("<{tag}>"), format!("</{tag}>"));
    xml.split(&open)
        .skip(1)
        .filter_map(|rest| rest.split_once(&close).map(|(text, _)| text.trim().to_string()))
        .collect()
}

fn single(xml: &str, tag: &str, path: &Path) -> String {
    let found = elements(xml, tag);
    assert_eq!(found.len(), 1, "{}: expected one <{tag}>, found {found:?}", path.display());
    found[0].clone()
}

fn package_xml(manifest_path: &str) -> (PathBuf, String) {
    let path = Path::new(manifest_path).with_file_name("package.xml");
    let xml = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (path, xml)
}

#[test]
fn every_node_crate_is_an_ament_cargo_package_matching_its_manifest() {
    let metadata = metadata();
    let packages = metadata["packages"].as_array().expect("packages");
    let mut ros_packages = BTreeSet::new();
    for name in ROS_CRATES {
        let package = packages.iter().find(|p| p["name"] == name).unwrap_or_else(|| panic!("crate {name}"));
        let (path, xml) = package_xml(package["manifest_path"].as_str().expect("manifest_path"));
        assert!(xml.contains("<package format=\"3\">"), "{}: not package format 3", path.display());
        assert_eq!(single(&xml, "name", &path), name, "{}", path.display());
        assert_eq!(single(&xml, "version", &path), package["version"].as_str().unwrap(), "{}", path.display());
        assert_eq!(single(&xml, "license", &path), package["license"].as_str().unwrap(), "{}", path.display());
        assert_eq!(single(&xml, "build_type", &path), "ament_cargo", "{}", path.display());
        assert!(!single(&xml, "description", &path).is_empty(), "{}", path.display());
        ros_packages.insert(name.to_string());
    }

    let root = packages.iter().find(|p| p["name"] == "rover").expect("the rover crate");
    let (path, xml) = package_xml(root["manifest_path"].as_str().unwrap());
    let build_dependencies: Vec<String> = ["depend", "build_depend"]
        .iter()
        .flat_map(|tag| elements(&xml, tag))
        .filter(|d| ros_packages.contains(d))
        .collect();
    assert!(build_dependencies.is_empty(), "{} declares {build_dependencies:?}", path.display());
    assert_eq!(elements(&xml, "exec_depend"), ["rover_msgs"], "{}: the interfaces it publishes", path.display());
}
