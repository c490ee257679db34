//! The import budget's environment variable (`samara_nn::limits::IMPORT_MEMORY_ENV`),
//! in a test binary of its own: one test sets the variable, so no other test of the
//! process reads it meanwhile.

use samara_nn::limits::IMPORT_MEMORY_ENV;

fn reference(name: &str) -> String {
    format!(
        "{}/../../../shared/reference/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

#[test]
fn the_variable_raises_or_lowers_the_budget_and_a_bad_value_is_named() {
    let file = reference("base_model_denorm.onnx");
    assert!(samara_nn::load(&file).is_ok());
    // Smaller than the file itself: refused before it is read.
    std::env::set_var(IMPORT_MEMORY_ENV, "1K");
    let e = samara_nn::load(&file).unwrap_err().to_string();
    assert!(e.contains(": file: the file has"), "{e}");
    assert!(e.contains("1,024 bytes (0.00 GiB) samara allows"), "{e}");
    assert!(e.contains(IMPORT_MEMORY_ENV), "{e}");
    std::env::set_var(IMPORT_MEMORY_ENV, "lots");
    let e = samara_nn::load(&file).unwrap_err().to_string();
    assert!(
        e.contains(&format!("{IMPORT_MEMORY_ENV}=`lots` is not a size")),
        "{e}"
    );
    std::env::set_var(IMPORT_MEMORY_ENV, "64M");
    assert!(samara_nn::load(&file).is_ok());
    std::env::remove_var(IMPORT_MEMORY_ENV);
}
