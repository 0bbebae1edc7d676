"""The headless command line: one module per subcommand (:mod:`.synth`,
:mod:`.export`) and the helpers they share (:mod:`.common`)."""
