"""exodaq's benchmark suite, driven by bench/run (see bench/README.md).

runner    the command line: builds, runs the parts, writes the JSON, calls the report
parts/    one module per part: measures and returns a JSON-ready dict, writes no prose
targets   every target, written once, with the summary row that shows it
report/   turns performance.json into performance.md and performance.png, measures nothing
"""
