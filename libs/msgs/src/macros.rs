/// Declares a message struct (fields in wire order) with its [`RosMessage`](crate::RosMessage)
/// and [`RosFieldType`](crate::RosFieldType) implementations.
macro_rules! ros_message {
    (
        $(#[$meta:meta])*
        $package:literal / $name:ident {
            $( $(#[$field_meta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )*
        }

        impl ros2_client::Message for $name {}

        impl $crate::RosMessage for $name {
            const PACKAGE: &'static str = $package;
            const NAME: &'static str = stringify!($name);
            fn fields() -> Vec<(&'static str, String)> {
                vec![ $( (stringify!($field).trim_start_matches("r#"), <$ty as $crate::RosFieldType>::ros_type()) ),* ]
            }
        }

        impl $crate::RosFieldType for $name {
            fn ros_type() -> String {
                format!("{}/{}", $package, stringify!($name))
            }
            fn add_definitions(definitions: &mut Vec<$crate::Definition>) {
                let type_name = <Self as $crate::RosFieldType>::ros_type();
                if definitions.iter().any(|d| d.type_name == type_name) {
                    return;
                }
                definitions.push($crate::Definition { type_name, fields: <Self as $crate::RosMessage>::fields() });
                $( <$ty as $crate::RosFieldType>::add_definitions(definitions); )*
            }
        }
    };
}
