//! The `package.xml` files and `COLCON_IGNORE` markers: only packages that install something
//! runnable or usable by ROS tools are ROS packages, and colcon sees only those. The root `rover` (format 3, `ament_cargo`, built by colcon-ros-cargo) installs
//! the executable and agrees with its Cargo manifest (name, version, licence); `rover_msgs` is the
//! interface package. The library crates the executable compiles from their paths carry none.

use std::path::{Path, PathBuf};

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
fn the_root_crate_is_an_ament_cargo_package_matching_its_manifest() {
    let metadata = metadata();
    let packages = metadata["packages"].as_array().expect("packages");
    let root = packages.iter().find(|p| p["name"] == "rover").expect("the rover crate");
    let (path, xml) = package_xml(root["manifest_path"].as_str().expect("manifest_path"));
    assert!(xml.contains("<package format=\"3\">"), "{}: not package format 3", path.display());
    assert_eq!(single(&xml, "name", &path), "rover", "{}", path.display());
    assert_eq!(single(&xml, "version", &path), root["version"].as_str().unwrap(), "{}", path.display());
    assert_eq!(single(&xml, "license", &path), root["license"].as_str().unwrap(), "{}", path.display());
    assert_eq!(single(&xml, "build_type", &path), "ament_cargo", "{}", path.display());
    assert!(!single(&xml, "description", &path).is_empty(), "{}", path.display());
    for tag in ["depend", "build_depend"] {
        assert!(elements(&xml, tag).is_empty(), "{}: builds from Cargo paths alone, no <{tag}>", path.display());
    }
    assert_eq!(elements(&xml, "exec_depend"), ["rover_msgs"], "{}: the interfaces it publishes", path.display());
}

#[test]
fn library_crates_are_not_ros_packages() {
    let metadata = metadata();
    let packages = metadata["packages"].as_array().expect("packages");
    let libraries_with_package_xml: Vec<String> = packages
        .iter()
        .filter(|p| p["name"] != "rover")
        .map(|p| Path::new(p["manifest_path"].as_str().expect("manifest_path")).with_file_name("package.xml"))
        .filter(|xml| xml.exists() && xml.parent() != Some(&Path::new(env!("CARGO_MANIFEST_DIR")).join("libs/msgs")))
        .map(|xml| xml.display().to_string())
        .collect();
    assert!(
        libraries_with_package_xml.is_empty(),
        "libraries that install nothing runnable: {libraries_with_package_xml:?}"
    );
}

#[test]
fn colcon_ignores_every_crate_but_the_two_packages() {
    let metadata = metadata();
    let packages = metadata["packages"].as_array().expect("packages");
    let msgs = Path::new(env!("CARGO_MANIFEST_DIR")).join("libs/msgs");
    let seen_by_colcon: Vec<String> = packages
        .iter()
        .filter(|p| p["name"] != "rover")
        .map(|p| {
            Path::new(p["manifest_path"].as_str().expect("manifest_path")).parent().expect("a folder").to_path_buf()
        })
        .filter(|folder| *folder != msgs && !folder.join("COLCON_IGNORE").exists())
        .map(|folder| folder.display().to_string())
        .collect();
    assert!(
        seen_by_colcon.is_empty(),
        "crates colcon-cargo would build on their own (add a COLCON_IGNORE): {seen_by_colcon:?}"
    );
}
