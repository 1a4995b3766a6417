//! DDS Security, turned on as ROS 2 turns it on: `ROS_SECURITY_ENABLE=true` and a keystore in the
//! sros2 layout at `ROS_SECURITY_KEYSTORE`; the process's enclave is `--ros-args --enclave NAME`
//! (default `/`), or `ROS_SECURITY_ENCLAVE_OVERRIDE`, and its files are in
//! `KEYSTORE/enclaves/NAME`. With `ROS_SECURITY_STRATEGY=Enforce` a missing file stops the
//! process; otherwise (`Permissive`, the default) it runs unsecured and says so.

use std::path::{Path, PathBuf};

use ros2_client::dds::rustdds::{DomainParticipantBuilder, DomainParticipantSecurityConfigFiles};

/// The files of an enclave, as sros2 names them (the ones DDS Security reads).
const ENCLAVE_FILES: [&str; 6] =
    ["identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s", "permissions.p7s"];

/// The enclave a process secures its participant with, if security is on.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Enclave {
    /// The folder of its files.
    pub(crate) dir: PathBuf,
}

/// The enclave the environment (read through `var`) and `--enclave` (`enclave_arg`) ask for:
/// `None` when security is off, or missing under the permissive strategy (logged).
pub(crate) fn enclave_from(
    var: impl Fn(&str) -> Option<String>,
    enclave_arg: Option<&str>,
) -> anyhow::Result<Option<Enclave>> {
    if var("ROS_SECURITY_ENABLE").as_deref() != Some("true") {
        return Ok(None);
    }
    let enforce = match var("ROS_SECURITY_STRATEGY").as_deref() {
        None | Some("" | "Permissive") => false,
        Some("Enforce") => true,
        Some(other) => anyhow::bail!("ROS_SECURITY_STRATEGY={other}: expected Enforce or Permissive"),
    };
    let name =
        var("ROS_SECURITY_ENCLAVE_OVERRIDE").or_else(|| enclave_arg.map(str::to_string)).unwrap_or_else(|| "/".into());
    let problem = match var("ROS_SECURITY_KEYSTORE").filter(|keystore| !keystore.is_empty()) {
        None => "ROS_SECURITY_KEYSTORE is not set".to_string(),
        Some(keystore) => {
            let dir = enclave_dir(Path::new(&keystore), &name)?;
            match ENCLAVE_FILES.iter().find(|file| !dir.join(file).is_file()) {
                None => return Ok(Some(Enclave { dir })),
                Some(missing) => {
                    format!("enclave {name}: no {} (expected the sros2 layout)", dir.join(missing).display())
                }
            }
        }
    };
    anyhow::ensure!(!enforce, "DDS Security is enforced but {problem}");
    tracing::warn!(
        "ROS_SECURITY_ENABLE=true but {problem}: running without DDS Security (ROS_SECURITY_STRATEGY=Permissive)"
    );
    Ok(None)
}

/// The folder of enclave `name` (absolute, like `/rover/bridge`) in `keystore`.
fn enclave_dir(keystore: &Path, name: &str) -> anyhow::Result<PathBuf> {
    anyhow::ensure!(name.starts_with('/'), "enclave {name:?}: expected an absolute name such as /rover/bridge");
    let parts: Vec<&str> = name.split('/').filter(|part| !part.is_empty()).collect();
    let valid = |part: &&str| part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    anyhow::ensure!(parts.iter().all(valid), "enclave {name:?}: expected names of letters, digits and _ between /");
    Ok(parts.iter().fold(keystore.join("enclaves"), |dir, part| dir.join(part)))
}

impl Enclave {
    /// `builder` with DDS Security's built-in plugins configured from this enclave's files.
    pub(crate) fn secure(&self, builder: DomainParticipantBuilder) -> DomainParticipantBuilder {
        builder.builtin_security(DomainParticipantSecurityConfigFiles::with_ros_default_names(&self.dir, String::new()))
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        move |name| map.get(name).cloned()
    }

    /// A keystore holding enclave `/rover/bridge` (empty files: only their presence is read here).
    fn keystore() -> PathBuf {
        let keystore = std::env::temp_dir().join(format!("rover-keystore-test-{}", std::process::id()));
        let dir = keystore.join("enclaves/rover/bridge");
        std::fs::create_dir_all(&dir).unwrap();
        for file in ENCLAVE_FILES {
            std::fs::write(dir.join(file), "").unwrap();
        }
        keystore
    }

    #[test]
    fn security_is_off_unless_enabled_and_the_enclave_comes_from_the_override_then_the_argument() {
        let keystore = keystore();
        let keystore = keystore.to_str().unwrap();
        assert_eq!(enclave_from(env(&[("ROS_SECURITY_KEYSTORE", keystore)]), Some("/rover/bridge")).unwrap(), None);
        let on = [("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_KEYSTORE", keystore)];
        let enclave = enclave_from(env(&on), Some("/rover/bridge")).unwrap().expect("an enclave");
        assert!(enclave.dir.ends_with("enclaves/rover/bridge"), "{:?}", enclave.dir);
        let overridden = [&on[..], &[("ROS_SECURITY_ENCLAVE_OVERRIDE", "/rover/bridge")]].concat();
        assert_eq!(enclave_from(env(&overridden), Some("/elsewhere")).unwrap(), Some(enclave));
    }

    #[test]
    fn a_missing_enclave_stops_an_enforced_process_and_leaves_a_permissive_one_unsecured() {
        let keystore = keystore();
        let keystore = keystore.to_str().unwrap();
        let on = [("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_KEYSTORE", keystore)];
        assert_eq!(enclave_from(env(&on), Some("/rover/mapping")).unwrap(), None);
        let enforced = [&on[..], &[("ROS_SECURITY_STRATEGY", "Enforce")]].concat();
        let error = enclave_from(env(&enforced), Some("/rover/mapping")).unwrap_err().to_string();
        assert!(error.contains("enclave /rover/mapping: no ") && error.contains("identity_ca.cert.pem"), "{error}");
        let unset = [("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_STRATEGY", "Enforce")];
        assert!(enclave_from(env(&unset), None).unwrap_err().to_string().contains("ROS_SECURITY_KEYSTORE is not set"));
    }

    #[test]
    fn enclave_names_cannot_leave_the_keystore() {
        let keystore = Path::new("/keys");
        assert_eq!(enclave_dir(keystore, "/rover/bridge").unwrap(), Path::new("/keys/enclaves/rover/bridge"));
        assert_eq!(enclave_dir(keystore, "/").unwrap(), Path::new("/keys/enclaves"));
        for bad in ["rover/bridge", "/rover/../../etc", "/rover/a b"] {
            assert!(enclave_dir(keystore, bad).is_err(), "{bad}");
        }
        let strategy = [("ROS_SECURITY_ENABLE", "true"), ("ROS_SECURITY_STRATEGY", "Strict")];
        assert!(enclave_from(env(&strategy), None).unwrap_err().to_string().contains("expected Enforce or Permissive"));
    }
}
