//! gantry, the motion master: CLI commands, demo, trace output.
