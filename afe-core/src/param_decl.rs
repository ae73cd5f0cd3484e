//! Parameters declared once: [`params!`](crate::params!) turns one declaration per field
//! (its AFE name, unit, meaning, type and default) into the parameter struct, its serde
//! names, its `Default`, its [`Params::SPECS`](crate::Params::SPECS) and a table of its
//! AFE names for error messages; [`choices!`](crate::choices!) does the same for a
//! parameter's accepted strings.

use crate::params::ParamKind;

/// The kind of value a field's type accepts, so that a declaration need not repeat it.
pub trait ParamType {
    /// What a request may give for a field of this type.
    const KIND: ParamKind;
}

/// An enum of accepted strings, declared by [`choices!`](crate::choices!): what a list
/// of it accepts.
pub trait Choice {
    /// The accepted strings, in declaration order.
    const NAMES: &'static [&'static str];
}

impl ParamType for f64 {
    const KIND: ParamKind = ParamKind::Number;
}

impl ParamType for u32 {
    const KIND: ParamKind = ParamKind::Count;
}

impl ParamType for bool {
    const KIND: ParamKind = ParamKind::Flag;
}

impl ParamType for String {
    const KIND: ParamKind = ParamKind::Text;
}

impl ParamType for Vec<f64> {
    const KIND: ParamKind = ParamKind::Numbers;
}

/// Absent (`[]`) or given: the kind of the value when given.
impl<T: ParamType> ParamType for Option<T> {
    const KIND: ParamKind = T::KIND;
}

impl<T: Choice> ParamType for Vec<T> {
    const KIND: ParamKind = ParamKind::Choices(T::NAMES);
}

/// Declares a parameter struct once: each field with its doc comment (its meaning, in
/// `afe list`), `#[afe = "prefix_name", unit = "s"]` (unit optional; `kind = ...`
/// overrides the kind its type implies, e.g. a bounded count), its type and its default.
/// The struct `Names` beside it holds each field's AFE name (`MyParams::NAMES.field`),
/// for the errors its processor reports.
///
/// ```
/// afe_core::params! {
///     /// The parameters of a demo processor.
///     pub struct DemoParams / DemoNames {
///         /// window length
///         #[afe = "demo_wSizeSec", unit = "s"]
///         pub w_size_sec: f64 = 0.02,
///         /// channels to keep
///         #[afe = "demo_nKeep", kind = afe_core::ParamKind::CountUpTo(8)]
///         pub keep: u32 = 2,
///     }
/// }
/// use afe_core::Params;
/// assert_eq!(DemoParams::NAMES.w_size_sec, "demo_wSizeSec");
/// assert_eq!(DemoParams::SPECS[1].kind, afe_core::ParamKind::CountUpTo(8));
/// assert_eq!(DemoParams::SPECS[0].meaning(), "window length");
/// assert_eq!(DemoParams::default().keep, 2);
/// ```
#[macro_export]
macro_rules! params {
    (
        $(#[doc = $sdoc:literal])*
        $vis:vis struct $name:ident / $names:ident {
            $(
                $(#[doc = $doc:literal])*
                #[afe = $afe:literal $(, unit = $unit:literal)? $(, kind = $kind:expr)?]
                $fvis:vis $field:ident : $ty:ty = $default:expr
            ),* $(,)?
        }
    ) => {
        $(#[doc = $sdoc])*
        #[derive(Debug, Clone, PartialEq, ::serde::Serialize, ::serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        $vis struct $name {
            $(
                $(#[doc = $doc])*
                #[serde(rename = $afe)]
                $fvis $field: $ty,
            )*
        }

        impl ::core::default::Default for $name {
            fn default() -> Self {
                $name { $($field: $default,)* }
            }
        }

        impl $crate::Params for $name {
            const SPECS: &'static [$crate::ParamSpec] = &[$(
                $crate::ParamSpec {
                    name: $afe,
                    kind: $crate::__param_kind!($ty $(, $kind)?),
                    unit: $crate::__param_unit!($($unit)?),
                    description: concat!($($doc),*),
                },
            )*];
        }

        #[doc = concat!("The AFE names of [`", stringify!($name), "`]'s parameters.")]
        #[derive(Debug, Clone, Copy)]
        $vis struct $names {
            $(
                #[doc = concat!("`", $afe, "`")]
                pub $field: &'static str,
            )*
        }

        impl $name {
            /// The AFE name of each field.
            pub const NAMES: $names = $names { $($field: $afe,)* };
        }
    };
}

/// Declares an enum of a parameter's accepted strings once: each variant with its
/// string. It (de)serialises as that string, lists them in [`Choice::NAMES`] and is a
/// [`ParamType`] of kind `Choice` (a `Vec` of it, `Choices`).
///
/// ```
/// afe_core::choices! {
///     /// A demo window.
///     pub enum Shape {
///         /// all ones
///         Flat = "flat",
///         Hump = "hump",
///     }
/// }
/// assert_eq!(Shape::NAMES, ["flat", "hump"]);
/// assert_eq!(Shape::Hump.name(), "hump");
/// ```
#[macro_export]
macro_rules! choices {
    (
        $(#[doc = $edoc:literal])*
        $vis:vis enum $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $variant:ident = $text:literal
            ),* $(,)?
        }
    ) => {
        $(#[doc = $edoc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, ::serde::Serialize, ::serde::Deserialize)]
        $vis enum $name {
            $(
                $(#[doc = $doc])*
                #[serde(rename = $text)]
                $variant,
            )*
        }

        impl $name {
            /// The accepted strings, in declaration order.
            pub const NAMES: &'static [&'static str] = &[$($text),*];

            /// The string of this choice.
            pub const fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)*
                }
            }
        }

        impl $crate::param_decl::Choice for $name {
            const NAMES: &'static [&'static str] = $name::NAMES;
        }

        impl $crate::param_decl::ParamType for $name {
            const KIND: $crate::ParamKind = $crate::ParamKind::Choice($name::NAMES);
        }

        impl ::core::fmt::Display for $name {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

/// The kind of a declared field: the one given, or the one its type implies.
#[doc(hidden)]
#[macro_export]
macro_rules! __param_kind {
    ($ty:ty, $kind:expr) => {
        $kind
    };
    ($ty:ty) => {
        <$ty as $crate::param_decl::ParamType>::KIND
    };
}

/// The unit of a declared field: the one given, or none.
#[doc(hidden)]
#[macro_export]
macro_rules! __param_unit {
    ($unit:literal) => {
        $unit
    };
    () => {
        ""
    };
}

#[cfg(test)]
mod tests {
    use crate::{ParamKind, Params};

    crate::choices! {
        /// Two shapes.
        enum Shape {
            Flat = "flat",
            Hump = "hump",
        }
    }

    crate::params! {
        /// Every kind a type implies.
        struct Every / EveryNames {
            /// a number
            /// over two lines
            #[afe = "t_x", unit = "Hz"]
            x: f64 = 1.5,
            #[afe = "t_n"]
            n: u32 = 3,
            #[afe = "t_on"]
            on: bool = true,
            #[afe = "t_count"]
            count: Option<u32> = None,
            #[afe = "t_v", unit = "dB"]
            v: Vec<f64> = vec![1.0],
            #[afe = "t_shape"]
            shape: Shape = Shape::Hump,
            #[afe = "t_shapes"]
            shapes: Vec<Shape> = vec![Shape::Flat],
            #[afe = "t_order", kind = ParamKind::CountUpTo(4)]
            order: u32 = 2,
        }
    }

    #[test]
    fn a_declaration_gives_the_specs_names_and_defaults() {
        let kinds: Vec<ParamKind> = Every::SPECS.iter().map(|s| s.kind).collect();
        assert_eq!(
            kinds,
            [
                ParamKind::Number,
                ParamKind::Count,
                ParamKind::Flag,
                ParamKind::Count,
                ParamKind::Numbers,
                ParamKind::Choice(&["flat", "hump"]),
                ParamKind::Choices(&["flat", "hump"]),
                ParamKind::CountUpTo(4),
            ]
        );
        assert_eq!(Every::SPECS[0].meaning(), "a number over two lines");
        assert_eq!((Every::SPECS[0].unit, Every::SPECS[1].unit), ("Hz", ""));
        let n = Every::NAMES;
        let names = [n.x, n.n, n.on, n.count, n.v, n.shape, n.shapes, n.order];
        let declared: Vec<&str> = Every::SPECS.iter().map(|s| s.name).collect();
        assert_eq!(names[..], declared[..]);
        let Every {
            x,
            n,
            on,
            count,
            v,
            shape,
            shapes,
            order,
        } = Every::default();
        assert_eq!(
            (x, n, on, count, v, shape, shapes, order),
            (
                1.5,
                3,
                true,
                None,
                vec![1.0],
                Shape::Hump,
                vec![Shape::Flat],
                2
            )
        );
        let map = Every::default().to_map();
        assert_eq!(map["t_shape"], serde_json::json!("hump"));
        assert_eq!(map["t_shapes"], serde_json::json!(["flat"]));
        assert_eq!(map["t_count"], serde_json::Value::Null);
        crate::params::check_param_specs::<Every>();
        let given: crate::ParamMap = [("t_shape".to_string(), serde_json::json!("flat"))].into();
        assert_eq!(
            Every::from_map(&given).map(|e| e.shape).ok(),
            Some(Shape::Flat)
        );
        assert_eq!(Shape::Flat.to_string(), "flat");
    }
}
