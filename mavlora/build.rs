fn main() {
    let out = std::env::var("OUT_DIR").unwrap();
    let xml = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("message_definitions/mavlora.xml");
    let r = mavlink_bindgen::generate(mavlink_bindgen::XmlDefinitions::Files(vec![xml]), &out).unwrap();
    mavlink_bindgen::emit_cargo_build_messages(&r);
    println!("cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\"))");
}
