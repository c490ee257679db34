//! Discrete-time system files (`next` updates, `mode ... in [...]`, `next M =
//! argmax(net)`, `networks by M`, `actuate u = a, b when M = V`): what they compile to,
//! checked against values computed by hand, and their errors with line and column.

use samara_system::System;

/// A two-state discrete plant with a three-valued mode: hand-checkable numbers.
const SRC: &str = "\
system toy
state x, v
input a
mode m in [LOW, MID, HIGH]
param k = 0.5
period 1
horizon 3
next x = x + v + k * a
next v = v + a
next m = argmax(net)
networks by m
actuate a = -1, 0, 1 when m = LOW
actuate a = 2 when m = MID
actuate a = 3, 4 when m = HIGH
init x in [0, 1]
init v = 2
init m = MID
goal avoid x in [10, 20] always
";

#[test]
fn a_discrete_file_compiles_to_its_update_mode_and_tables() {
    let sys = System::parse(SRC, "toy.sys").unwrap();
    assert!(sys.is_discrete());
    assert_eq!(sys.steps(), 3);
    let d = sys.discrete.as_ref().unwrap();
    let m = d.mode.as_ref().unwrap();
    assert_eq!(m.values, ["LOW", "MID", "HIGH"]);
    assert_eq!((m.init, m.networks_by), (1, true));
    assert_eq!(m.tables.len(), 1);
    assert_eq!(m.tables[0].input, 0);
    assert_eq!(
        m.tables[0].values,
        vec![vec![-1.0, 0.0, 1.0], vec![2.0], vec![3.0, 4.0]]
    );
    // The argmax reads one output per mode value.
    assert_eq!(sys.n_net_outputs, 3);
    // By hand: x = 1, v = 2, a = 4: x' = 1 + 2 + 0.5 * 4 = 5, v' = 6.
    let mut out = [0.0; 2];
    sys.next_state(&[1.0, 2.0], &[4.0], &mut out);
    assert_eq!(out, [5.0, 6.0]);
    // A discrete system has no flow: its right-hand side is zero, and the simulator of
    // flows refuses it.
    let mut dx = [1.0; 2];
    sys.rhs(&[1.0, 2.0], &[4.0], &mut dx);
    assert_eq!(dx, [0.0, 0.0]);
    let e = samara_system::sim::fly(&sys, &|_| vec![0.0; 3], &[0.0, 2.0], 1).unwrap_err();
    assert_eq!(e, samara_system::sim::SimError::Discrete);
}

#[test]
fn a_discrete_file_without_a_mode_uses_its_actuation() {
    let src = "state x\ninput u\nperiod 0.5\nhorizon 1\nnext x = 2 * x + u\nactuate u = 3 * net[0] clip [-1, 1]\ninit x = 1\n";
    let sys = System::parse(src, "t.sys").unwrap();
    assert!(sys.is_discrete() && sys.discrete.as_ref().unwrap().mode.is_none());
    let mut u = [0.0];
    sys.actuate(&[0.25], &mut u);
    assert_eq!(u, [0.75]);
    let mut out = [0.0];
    sys.next_state(&[1.5], &u, &mut out);
    assert_eq!(out, [3.75]);
}

fn err(src: &str) -> samara_system::SystemError {
    System::parse(src, "t.sys").unwrap_err()
}

fn with(line: &str, replaced: &str) -> String {
    assert!(SRC.contains(line));
    SRC.replace(line, replaced)
}

#[test]
fn discrete_errors_name_line_column_and_fix() {
    // Derivative in a discrete file.
    let e = err(&with("next v = v + a", "v' = a"));
    assert_eq!((e.pos.line, e.pos.col), (9, 1), "{e}");
    assert!(e.message.contains("discrete-time"), "{e}");
    // Update of an undefined state, with a suggestion.
    let e = err(&with("next v = v + a", "next vv = v + a"));
    assert_eq!((e.pos.line, e.pos.col), (9, 6), "{e}");
    assert!(e.hint.contains("next v"), "{e}");
    // A state without update.
    let e = err(&with("next v = v + a\n", ""));
    assert_eq!((e.pos.line, e.pos.col), (2, 10), "{e}");
    assert!(e.message.contains("no update"), "{e}");
    // A value that is not the mode's.
    let e = err(&with("when m = MID", "when m = MIDDLE"));
    assert_eq!((e.pos.line, e.pos.col), (13, 24), "{e}");
    assert!(e.hint.contains("MID"), "{e}");
    // A mode value without table row.
    let e = err(&with("actuate a = 2 when m = MID\n", ""));
    assert_eq!(e.pos.line, 12, "{e}");
    assert!(e.message.contains("no values for `m = MID`"), "{e}");
    // A mode without argmax update.
    let e = err(&with("next m = argmax(net)\n", ""));
    assert_eq!((e.pos.line, e.pos.col), (4, 6), "{e}");
    assert!(e.hint.contains("argmax"), "{e}");
    // A mode updated by an expression.
    let e = err(&with("next m = argmax(net)", "next m = x"));
    assert_eq!((e.pos.line, e.pos.col), (10, 6), "{e}");
    // An argmax over something else than the network.
    let e = err(&with("argmax(net)", "argmax(x)"));
    assert_eq!((e.pos.line, e.pos.col), (10, 17), "{e}");
    // A table and an actuate line for one input.
    let e = err(&with("networks by m", "networks by m\nactuate a = net[0]"));
    assert!(e.message.contains("actuated twice"), "{e}");
    // A value listed twice, and `init` of a mode with a number.
    let e = err(&with("[LOW, MID, HIGH]", "[LOW, MID, LOW]"));
    assert_eq!((e.pos.line, e.pos.col), (4, 22), "{e}");
    let e = err(&with("init m = MID", "init m = 1"));
    assert_eq!((e.pos.line, e.pos.col), (17, 10), "{e}");
    // `reset` has no meaning in a discrete file.
    let e = err(&with("init v = 2", "init v = 2\nreset v = 0"));
    assert!(e.message.contains("continuous-time"), "{e}");
}
