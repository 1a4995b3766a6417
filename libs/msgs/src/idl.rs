//! A small parser for ROS 2 `.msg` files: fields, constants and leading comments.
//!
//! It is shared by `build.rs` (which generates the Rust types of `rover_msgs`) and by the tests
//! that check hand-written standard message types against the installed `.msg` files.

/// One field of a message: its name and its normalised ROS type (for example `float64[9]`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldSpec {
    /// Field name as written in the `.msg` file.
    pub name: String,
    /// Normalised type: `byte` and `char` become `uint8`, bounds are dropped, `Header` gets its package.
    pub ros_type: String,
    /// Comment lines written directly above the field.
    pub doc: Vec<String>,
}

/// One constant of a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConstantSpec {
    /// Constant name.
    pub name: String,
    /// Normalised ROS type of the constant.
    pub ros_type: String,
    /// Value as written.
    pub value: String,
}

/// A parsed message definition.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MessageSpec {
    /// Leading comment block of the file (before the first blank line that follows it).
    pub doc: Vec<String>,
    /// Fields in wire order.
    pub fields: Vec<FieldSpec>,
    /// Constants in file order.
    pub constants: Vec<ConstantSpec>,
}

/// Parses the text of a `.msg` file of package `package`.
pub fn parse_msg(package: &str, text: &str) -> Result<MessageSpec, String> {
    let mut spec = MessageSpec::default();
    let mut pending_doc: Vec<String> = Vec::new();
    let mut in_header_doc = true;
    for (index, raw_line) in text.lines().enumerate() {
        let line_number = index + 1;
        let (code, comment) = split_comment(raw_line);
        let code = code.trim();
        if code.is_empty() {
            match comment {
                Some(comment) => pending_doc.push(comment.trim().to_string()),
                None => {
                    if in_header_doc && !pending_doc.is_empty() {
                        spec.doc.append(&mut pending_doc);
                        in_header_doc = false;
                    }
                    pending_doc.clear();
                }
            }
            continue;
        }
        in_header_doc = false;
        let mut doc = std::mem::take(&mut pending_doc);
        if let Some(comment) = comment {
            doc.push(comment.trim().to_string());
        }
        if let Some((declaration, value)) = split_constant(code) {
            let (ros_type, name) = split_declaration(declaration.trim())
                .ok_or_else(|| format!("line {line_number}: expected `TYPE NAME=VALUE`, got {code:?}"))?;
            spec.constants.push(ConstantSpec {
                name: name.to_string(),
                ros_type: normalize_type(package, ros_type),
                value: value.trim().to_string(),
            });
        } else {
            let mut parts = code.split_whitespace();
            let (Some(ros_type), Some(name)) = (parts.next(), parts.next()) else {
                return Err(format!("line {line_number}: expected `TYPE NAME`, got {code:?}"));
            };
            spec.fields.push(FieldSpec { name: name.to_string(), ros_type: normalize_type(package, ros_type), doc });
        }
    }
    Ok(spec)
}

fn split_comment(line: &str) -> (&str, Option<&str>) {
    match line.find('#') {
        Some(at) => (&line[..at], Some(&line[at + 1..])),
        None => (line, None),
    }
}

/// Splits `TYPE NAME=VALUE` at the `=` that is not part of a `<=` bound.
fn split_constant(code: &str) -> Option<(&str, &str)> {
    let at = code.char_indices().find(|&(i, c)| c == '=' && !code[..i].ends_with('<'))?.0;
    Some((&code[..at], &code[at + 1..]))
}

fn split_declaration(declaration: &str) -> Option<(&str, &str)> {
    let mut parts = declaration.split_whitespace();
    Some((parts.next()?, parts.next()?))
}

/// Normalises a ROS type as written in a `.msg` file of `package`.
pub fn normalize_type(package: &str, ros_type: &str) -> String {
    let (element, array) = match ros_type.find('[') {
        Some(at) => (&ros_type[..at], normalize_array_suffix(&ros_type[at..])),
        None => (ros_type, String::new()),
    };
    let element = element.split("<=").next().unwrap_or(element);
    let element = match element {
        "byte" | "char" => "uint8".to_string(),
        "Header" => "std_msgs/Header".to_string(),
        primitive if is_primitive(primitive) => primitive.to_string(),
        qualified if qualified.contains('/') => qualified.replace("/msg/", "/"),
        local => format!("{package}/{local}"),
    };
    format!("{element}{array}")
}

fn normalize_array_suffix(suffix: &str) -> String {
    if suffix.starts_with("[<=") { "[]".to_string() } else { suffix.to_string() }
}

/// True for the ROS primitive types (after `byte`/`char` normalisation).
pub fn is_primitive(ros_type: &str) -> bool {
    matches!(
        ros_type,
        "bool"
            | "int8"
            | "uint8"
            | "int16"
            | "uint16"
            | "int32"
            | "uint32"
            | "int64"
            | "uint64"
            | "float32"
            | "float64"
            | "string"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_fields_constants_and_docs() {
        let text = "# A doc line\n\nuint8 A = 3 # three\n# about x\nfloat64 x\nHeader header\nbyte[] raw\nfloat64[9] k\nstring<=8 s\nint32[<=4] b\ngeometry_msgs/msg/Pose p\nKeyValue[] values\n";
        let spec = parse_msg("pkg", text).unwrap();
        assert_eq!(spec.doc, vec!["A doc line"]);
        assert_eq!(spec.constants[0].name, "A");
        assert_eq!(spec.constants[0].value, "3");
        let types: Vec<_> = spec.fields.iter().map(|f| (f.name.as_str(), f.ros_type.as_str())).collect();
        assert_eq!(
            types,
            vec![
                ("x", "float64"),
                ("header", "std_msgs/Header"),
                ("raw", "uint8[]"),
                ("k", "float64[9]"),
                ("s", "string"),
                ("b", "int32[]"),
                ("p", "geometry_msgs/Pose"),
                ("values", "pkg/KeyValue[]"),
            ]
        );
        assert_eq!(spec.fields[0].doc, vec!["about x"]);
    }

    #[test]
    fn rejects_a_line_without_a_name() {
        let error = parse_msg("pkg", "float64\n").unwrap_err();
        assert!(error.contains("line 1"), "{error}");
    }
}
