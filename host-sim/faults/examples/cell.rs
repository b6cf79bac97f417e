//! Runs one cell and prints it: `cargo run --release -p faults --example cell -- KIND CONDITION`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(k), Some(c)) = (
        args.get(1).and_then(|a| faults::FaultKind::from_name(a)),
        args.get(2).and_then(|a| faults::Condition::from_name(a)),
    ) else {
        eprintln!("usage: cell KIND CONDITION");
        std::process::exit(2);
    };
    match faults::run_cell(k, c) {
        Ok(cell) => println!("{cell:#?}"),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
