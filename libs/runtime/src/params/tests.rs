#![allow(unreachable_pub)] // the parameter macro declares public items, here in a test module

use super::*;

crate::node_params! {
    /// Test parameters.
    pub struct TestParams {
        /// A port.
        port: i64 [1, 65535] = 4567,
        /// A deadline in ms.
        deadline_ms: f64 [0.0, 1000.0] = 50.0,
        /// A host.
        host: String = "127.0.0.1",
        /// Points.
        points: Vec<f64> = vec![1.0, 2.0],
        /// A flag.
        enabled: bool = true,
    }
}

fn assignment(name: &str, text: &str) -> Assignment {
    Assignment { name: name.into(), value: parse_override(text).unwrap(), source_name: format!("-p {name}:={text}") }
}

#[test]
fn defaults_then_overrides() {
    let values =
        resolve_values("t", &TestParams::specs(), &[assignment("port", "4568"), assignment("deadline_ms", "20")])
            .unwrap();
    let params = TestParams::from_values(&values);
    assert_eq!(params.port, 4568);
    assert_eq!(params.deadline_ms, 20.0);
    assert_eq!(params.host, "127.0.0.1");
    assert_eq!(params.points, vec![1.0, 2.0]);
    assert_eq!(TestParams::default().port, 4567);
}

#[test]
fn use_sim_time_is_accepted_as_a_boolean_only() {
    let values = resolve_values("t", &TestParams::specs(), &[assignment("use_sim_time", "true")]).unwrap();
    assert_eq!(values.get("use_sim_time"), Some(&ParameterValue::Boolean(true)));
    assert_eq!(TestParams::from_values(&values).port, 4567);
    let defaults = resolve_values("t", &TestParams::specs(), &[]).unwrap();
    assert_eq!(defaults.get("use_sim_time"), None, "left to ros2-client's built-in default");
    let wrong = resolve_values("t", &TestParams::specs(), &[assignment("use_sim_time", "1")]).unwrap_err();
    assert!(wrong.to_string().contains("`use_sim_time`") && wrong.to_string().contains("a boolean"), "{wrong}");
}

#[test]
fn descriptions_come_from_doc_comments() {
    let specs = TestParams::specs();
    assert_eq!(specs[0].description, "A port.");
    assert_eq!(specs[0].range, Some((1.0, 65535.0)));
    assert!(help_table(&specs).contains("port (an integer, range [1, 65535], default 4567)"));
}

#[test]
fn unknown_wrong_type_and_out_of_range_are_rejected() {
    let specs = TestParams::specs();
    let unknown = resolve_values("t", &specs, &[assignment("prot", "1")]).unwrap_err();
    assert!(unknown.to_string().contains("unknown parameter `prot`"), "{unknown}");
    assert!(unknown.to_string().contains("known parameters: port"), "{unknown}");
    let wrong = resolve_values("t", &specs, &[assignment("port", "abc")]).unwrap_err();
    assert!(wrong.to_string().contains("expects an integer, got \"abc\""), "{wrong}");
    let range = resolve_values("t", &specs, &[assignment("port", "70000")]).unwrap_err();
    assert!(range.to_string().contains("outside the allowed range"), "{range}");
    let nan = resolve_values("t", &specs, &[assignment("deadline_ms", ".nan")]).unwrap_err();
    assert!(nan.to_string().contains("finite number"), "{nan}");
}

#[test]
fn yaml_sections_apply_by_node_name() {
    let yaml = "/**:\n  ros__parameters:\n    enabled: false\nbridge:\n  ros__parameters:\n    port: 5000\n    nested:\n      a: 1\nother:\n  ros__parameters:\n    port: 1\n";
    let assignments = assignments_from_yaml(yaml, "p.yaml", "/bridge").unwrap();
    let names: Vec<_> = assignments.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, vec!["enabled", "port", "nested.a"]);
    assert_eq!(assignments[1].value, ParameterValue::Integer(5000));
}

#[test]
fn yaml_errors_are_explained() {
    let error = assignments_from_yaml("bridge:\n  port: 1\n", "p.yaml", "/bridge").unwrap_err();
    assert!(error.contains("no `ros__parameters`"), "{error}");
    assert!(assignments_from_yaml("[1, 2", "p.yaml", "/bridge").unwrap_err().contains("invalid YAML"));
}

/// Fuzz targets: parameter files and `-p` values are any text; they parse or give an error,
/// never a panic, and every assignment read names its source.
mod fuzz {
    use proptest::prelude::*;
    use rover_fuzzing::mutation::mutated_text;

    use super::*;

    /// The launch parameter file and a small file with nested and list values.
    fn valid_files() -> Vec<String> {
        let nested = "/**:\n  ros__parameters:\n    a: {b: [1, 2.5], c: [true]}\n    d: ~\n    e: [x, y]\n";
        vec![include_str!("../../../../launch_scripts/rover_params.yaml").to_string(), nested.to_string()]
    }

    fn check_file(text: &str) -> Result<(), TestCaseError> {
        for node in ["/bridge", "/mapping", "/ns/decision"] {
            if let Ok(assignments) = assignments_from_yaml(text, "fuzz.yaml", node) {
                prop_assert!(assignments.iter().all(|a| a.source_name == "fuzz.yaml"));
            }
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn fuzz_params_arbitrary_yaml(text in "\\PC{0,200}") {
            check_file(&text)?;
        }

        #[test]
        fn fuzz_params_mutated_yaml(text in mutated_text(valid_files())) {
            check_file(&text)?;
        }

        #[test]
        fn fuzz_params_arbitrary_override(text in "\\PC{0,40}") {
            if let Ok(value) = parse_override(&text) {
                let _ = check_value(&TestParams::specs()[0], &value);
            }
        }
    }
}
