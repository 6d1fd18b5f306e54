//! experiment
#[allow(non_camel_case_types, non_snake_case, clippy::all, missing_docs, unused)]
pub mod mavlora {
    include!(concat!(env!("OUT_DIR"), "/mavlora.rs"));
}
