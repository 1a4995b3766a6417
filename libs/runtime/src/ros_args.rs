//! The ROS 2 command-line arguments: `--ros-args -r from:=to -p name:=value --params-file FILE`,
//! and the logging ones: `--log-level [LOGGER:=]LEVEL`, `--disable-rosout-logs`,
//! `--disable-stdout-logs`, `--disable-external-lib-logs` (and their `--enable-` forms); and the
//! DDS Security enclave, `-e`/`--enclave NAME`.
//!
//! Everything between `--ros-args` and a lone `--` (or the end) belongs to ROS; the rest is left for
//! the program's own parser. A remap or parameter may be restricted to one node with a `node:` prefix,
//! e.g. `-r bridge:__ns:=/rover1` or `-p mapping:range_m:=6.0`.

use std::path::PathBuf;

/// Errors in the ROS arguments, each naming the bad argument and what was expected.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RosArgsError {
    /// An option is missing its value.
    #[error("`{0}` needs a value after it")]
    MissingValue(String),
    /// A remap or parameter is not of the form `name:=value`.
    #[error("`{0}` is not of the form NAME:=VALUE")]
    NotAnAssignment(String),
    /// A log level that is not one of ROS's.
    #[error("`--log-level {0}`: expected debug, info, warn, error or fatal, or LOGGER:=LEVEL (e.g. bridge:=debug)")]
    LogLevel(String),
    /// An argument inside `--ros-args` that ROS does not know, or that means nothing here.
    #[error(
        "unknown ROS argument `{0}` (expected -r/--remap, -p/--param, --params-file, --log-level, -e/--enclave, \
         --disable-rosout-logs, --disable-stdout-logs, --disable-external-lib-logs or --)"
    )]
    Unknown(String),
}

/// One `from:=to` remap rule, optionally for a single node.
#[derive(Debug, Clone, PartialEq)]
pub struct Remap {
    /// Node the rule applies to, or `None` for every node of the process.
    pub node: Option<String>,
    /// Name to replace (`__ns` and `__node` are special).
    pub from: String,
    /// Replacement.
    pub to: String,
}

/// One `-p name:=value` override, optionally for a single node.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamOverride {
    /// Node the override applies to, or `None` for every node.
    pub node: Option<String>,
    /// Parameter name.
    pub name: String,
    /// Value as written (parsed as a YAML scalar or list later).
    pub value: String,
}

/// The ROS arguments of one process.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// Remap rules in command-line order.
    pub remaps: Vec<Remap>,
    /// Parameter overrides in command-line order (later wins).
    pub params: Vec<ParamOverride>,
    /// Parameter YAML files in command-line order (later wins).
    pub params_files: Vec<PathBuf>,
    /// The logging arguments.
    pub logs: LogArgs,
    /// `-e`/`--enclave`: the DDS Security enclave of the process (see `ROS_SECURITY_ENABLE`).
    pub enclave: Option<String>,
}

/// What `--ros-args` say about the logs of the process.
#[derive(Debug, Clone, PartialEq)]
pub struct LogArgs {
    /// `--log-level LEVEL`: the level of every log, as `tracing` names it.
    pub level: Option<&'static str>,
    /// `--log-level LOGGER:=LEVEL`, in order: the level of one node's log. LOGGER is the node's
    /// ROS logger name, its name (`bridge`, in any namespace) or namespace and name (`rover1.bridge`).
    pub node_levels: Vec<(String, &'static str)>,
    /// Whether nodes publish their log on `/rosout` (`--disable-rosout-logs`).
    pub rosout: bool,
    /// Whether the process writes its log to the console, stderr (`--disable-stdout-logs`).
    pub console: bool,
}

impl Default for LogArgs {
    fn default() -> Self {
        LogArgs { level: None, node_levels: Vec::new(), rosout: true, console: true }
    }
}

/// Splits `argv` into the program's own arguments and the parsed ROS arguments.
pub fn split_ros_args(argv: Vec<String>) -> Result<(Vec<String>, RosArgs), RosArgsError> {
    let mut own = Vec::new();
    let mut ros = RosArgs::default();
    let mut args = argv.into_iter();
    while let Some(arg) = args.next() {
        if arg != "--ros-args" {
            own.push(arg);
            continue;
        }
        while let Some(arg) = args.next() {
            match arg.as_str() {
                "--" => break,
                "--ros-args" => {}
                "-r" | "--remap" => {
                    let (node, from, to) = parse_assignment(&arg, args.next())?;
                    ros.remaps.push(Remap { node, from, to });
                }
                "-p" | "--param" => {
                    let (node, name, value) = parse_assignment(&arg, args.next())?;
                    ros.params.push(ParamOverride { node, name, value });
                }
                "--params-file" => {
                    let file = args.next().ok_or_else(|| RosArgsError::MissingValue(arg.clone()))?;
                    ros.params_files.push(PathBuf::from(file));
                }
                "--log-level" => {
                    let value = args.next().ok_or_else(|| RosArgsError::MissingValue(arg.clone()))?;
                    ros.logs.set_level(&value)?;
                }
                "-e" | "--enclave" => {
                    ros.enclave = Some(args.next().ok_or_else(|| RosArgsError::MissingValue(arg.clone()))?);
                }
                "--disable-rosout-logs" | "--enable-rosout-logs" => ros.logs.rosout = arg.starts_with("--enable"),
                "--disable-stdout-logs" | "--enable-stdout-logs" => ros.logs.console = arg.starts_with("--enable"),
                // The external library is rcl's log file; no node here writes one.
                "--disable-external-lib-logs" | "--enable-external-lib-logs" => {}
                other if other.contains(":=") => {
                    let (node, from, to) = parse_assignment("-r", Some(other.to_string()))?;
                    ros.remaps.push(Remap { node, from, to });
                }
                other => return Err(RosArgsError::Unknown(other.to_string())),
            }
        }
    }
    Ok((own, ros))
}

impl LogArgs {
    /// Applies one `--log-level` value: `LEVEL` or `LOGGER:=LEVEL`.
    fn set_level(&mut self, value: &str) -> Result<(), RosArgsError> {
        let bad = || RosArgsError::LogLevel(value.to_string());
        match value.split_once(":=") {
            None => self.level = Some(tracing_level(value).ok_or_else(bad)?),
            Some((logger, level)) => {
                let ros_name = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '.' || c == '/';
                if logger.is_empty() || !logger.chars().all(ros_name) {
                    return Err(bad());
                }
                self.node_levels.push((logger.to_string(), tracing_level(level).ok_or_else(bad)?));
            }
        }
        Ok(())
    }
}

/// The `tracing` level of a ROS log level, in any case; ROS's `fatal` is `tracing`'s `error`.
fn tracing_level(ros_level: &str) -> Option<&'static str> {
    match ros_level.to_ascii_lowercase().as_str() {
        "debug" => Some("debug"),
        "info" => Some("info"),
        "warn" | "warning" => Some("warn"),
        "error" | "fatal" => Some("error"),
        _ => None,
    }
}

fn parse_assignment(option: &str, value: Option<String>) -> Result<(Option<String>, String, String), RosArgsError> {
    let value = value.ok_or_else(|| RosArgsError::MissingValue(option.to_string()))?;
    let (lhs, rhs) = value.split_once(":=").ok_or_else(|| RosArgsError::NotAnAssignment(value.clone()))?;
    let (node, name) = match lhs.split_once(':') {
        Some((node, name)) => (Some(node.to_string()), name),
        None => (None, lhs),
    };
    if name.is_empty() {
        return Err(RosArgsError::NotAnAssignment(value.clone()));
    }
    Ok((node, name.to_string(), rhs.to_string()))
}

impl RosArgs {
    /// Remap rules that apply to the node originally named `node`.
    pub fn remaps_for<'a>(&'a self, node: &'a str) -> impl Iterator<Item = &'a Remap> + 'a {
        self.remaps.iter().filter(move |r| r.node.as_deref().is_none_or(|n| n == node))
    }

    /// Parameter overrides that apply to the node originally named `node`.
    pub fn params_for<'a>(&'a self, node: &'a str) -> impl Iterator<Item = &'a ParamOverride> + 'a {
        self.params.iter().filter(move |p| p.node.as_deref().is_none_or(|n| n == node))
    }

    /// The `__special` remap for `node` (`__ns` or `__node`), the last one winning.
    pub fn special_for(&self, node: &str, special: &str) -> Option<String> {
        self.remaps_for(node).filter(|r| r.from == special).last().map(|r| r.to.clone())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `args` as owned strings.
    pub(crate) fn strings(args: &[&str]) -> Vec<String> {
        args.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn separates_own_and_ros_arguments() {
        let argv = strings(&[
            "rover",
            "bridge",
            "--ros-args",
            "-r",
            "odom:=odometry",
            "-p",
            "port:=4568",
            "--params-file",
            "a.yaml",
            "-r",
            "__ns:=/r1",
            "--",
            "--verbose",
        ]);
        let (own, ros) = split_ros_args(argv).unwrap();
        assert_eq!(own, strings(&["rover", "bridge", "--verbose"]));
        assert_eq!(ros.remaps[0], Remap { node: None, from: "odom".into(), to: "odometry".into() });
        assert_eq!(ros.params[0].name, "port");
        assert_eq!(ros.params[0].value, "4568");
        assert_eq!(ros.params_files, vec![PathBuf::from("a.yaml")]);
        assert_eq!(ros.special_for("bridge", "__ns").as_deref(), Some("/r1"));
    }

    #[test]
    fn node_prefixed_rules_apply_to_that_node_only() {
        let argv = strings(&["rover", "--ros-args", "-r", "bridge:__node:=b2", "-p", "mapping:range_m:=6.5"]);
        let (_, ros) = split_ros_args(argv).unwrap();
        assert_eq!(ros.special_for("bridge", "__node").as_deref(), Some("b2"));
        assert_eq!(ros.special_for("mapping", "__node"), None);
        assert_eq!(ros.params_for("mapping").count(), 1);
        assert_eq!(ros.params_for("bridge").count(), 0);
    }

    #[test]
    fn bare_assignment_is_a_remap() {
        let (_, ros) = split_ros_args(strings(&["x", "--ros-args", "__ns:=/a"])).unwrap();
        assert_eq!(ros.special_for("n", "__ns").as_deref(), Some("/a"));
    }

    #[test]
    fn errors_name_the_bad_argument() {
        assert_eq!(
            split_ros_args(strings(&["x", "--ros-args", "-p", "port"])).unwrap_err(),
            RosArgsError::NotAnAssignment("port".into())
        );
        assert_eq!(
            split_ros_args(strings(&["x", "--ros-args", "-r"])).unwrap_err(),
            RosArgsError::MissingValue("-r".into())
        );
        assert_eq!(
            split_ros_args(strings(&["x", "--ros-args", "--bogus"])).unwrap_err(),
            RosArgsError::Unknown("--bogus".into())
        );
    }

    #[test]
    fn log_levels_are_read_as_ros_writes_them_for_the_process_or_one_node() {
        let argv = [
            "x",
            "--ros-args",
            "--log-level",
            "WARN",
            "--log-level",
            "bridge:=Debug",
            "--log-level",
            "rover1.mapping:=fatal",
        ];
        let (_, ros) = split_ros_args(strings(&argv)).unwrap();
        assert_eq!(ros.logs.level, Some("warn"));
        assert_eq!(ros.logs.node_levels, [("bridge".to_string(), "debug"), ("rover1.mapping".to_string(), "error")]);
        for bad in ["loud", "bridge:=loud", ":=debug", "a b:=debug"] {
            let error = split_ros_args(strings(&["x", "--ros-args", "--log-level", bad])).unwrap_err();
            assert_eq!(error, RosArgsError::LogLevel(bad.into()));
            assert!(error.to_string().contains("expected debug, info, warn, error or fatal"), "{error}");
        }
    }

    #[test]
    fn the_enclave_is_read_in_either_form() {
        let (_, ros) = split_ros_args(strings(&["x", "--ros-args", "-e", "/rover/bridge"])).unwrap();
        assert_eq!(ros.enclave.as_deref(), Some("/rover/bridge"));
        let (_, ros) = split_ros_args(strings(&["x", "--ros-args", "--enclave", "/a"])).unwrap();
        assert_eq!(ros.enclave.as_deref(), Some("/a"));
        assert_eq!(
            split_ros_args(strings(&["x", "--ros-args", "-e"])).unwrap_err(),
            RosArgsError::MissingValue("-e".into())
        );
    }

    #[test]
    fn rosout_and_console_logs_can_be_turned_off_and_on_again() {
        let (_, ros) =
            split_ros_args(strings(&["x", "--ros-args", "--disable-rosout-logs", "--disable-stdout-logs"])).unwrap();
        assert_eq!((ros.logs.rosout, ros.logs.console), (false, false));
        let argv = ["x", "--ros-args", "--disable-rosout-logs", "--enable-rosout-logs", "--disable-external-lib-logs"];
        let (_, ros) = split_ros_args(strings(&argv)).unwrap();
        assert_eq!((ros.logs.rosout, ros.logs.console), (true, true));
        assert_eq!(split_ros_args(strings(&["x"])).unwrap().1.logs, LogArgs::default());
    }

    /// Fuzz targets: any argument vector splits into own and ROS arguments or gives an error,
    /// never a panic; own arguments keep their order and no parsed rule has an empty name.
    mod fuzz {
        use proptest::prelude::*;

        use super::*;

        /// An argument: an option the parser knows, an assignment, or any text.
        fn argument() -> impl Strategy<Value = String> {
            let options = vec![
                "--ros-args",
                "--",
                "-r",
                "--remap",
                "-p",
                "--param",
                "--params-file",
                "--log-level",
                "--disable-rosout-logs",
                "--disable-stdout-logs",
                "-e",
            ];
            prop_oneof![
                3 => proptest::sample::select(options).prop_map(String::from),
                3 => "[a-z/~:=_]{0,12}",
                1 => "\\PC{0,12}",
            ]
        }

        proptest! {
            #[test]
            fn fuzz_ros_args_arbitrary_argv(argv in proptest::collection::vec(argument(), 0..16)) {
                if let Ok((own, ros)) = split_ros_args(argv.clone()) {
                    let mut rest = argv.iter();
                    prop_assert!(own.iter().all(|arg| rest.any(|a| a == arg)));
                    prop_assert!(ros.remaps.iter().all(|r| !r.from.is_empty()));
                    prop_assert!(ros.params.iter().all(|p| !p.name.is_empty()));
                }
            }
        }
    }
}
