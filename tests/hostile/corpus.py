"""The hostile-input corpus: every bad invocation a new user tried, with what must happen.

Each case is ``(id, argv, exit code, needle)``.  ``argv`` may use these placeholders,
filled in by ``tests/hostile/test_corpus.py`` in a fresh folder per case:

``{D}``        a copy of ``tests/data/hostile/`` (the static hostile files)
``{T}``        the case's scratch folder (outputs go there)
``{NESTED}``   a JSON file nested 200,000 deep (made on the fly: 400 kB)
``{FIFO}``     a named pipe;  ``{ZERO}`` ``/dev/zero``
``{FILE}``     an existing regular file that is not a folder
``{FOREIGN}``  a folder holding a file unseen did not write

The needle must appear in the single line on stderr.  Exit 2 is bad input (one line, no
traceback); every input file must be byte-identical afterwards.
"""

from __future__ import annotations

S = "{D}/stable.json"

CASES: list[tuple[str, list[str], int, str]] = [
    # ---- check: numbers, nesting, ids, sizes, densities, special files, flags
    ("check-400-digit-size", ["check", "{D}/size_400_digits.json"], 2, "400 digits"),
    ("check-nested-200k", ["check", "{NESTED}"], 2, "nested 200000 levels"),
    ("check-id-nul", ["check", "{D}/id_nul.json", "--engine", "all"], 2, "U+0000"),
    ("check-id-bel-mujoco", ["check", "{D}/id_bel.json", "--engine", "mujoco"], 2, "U+0007"),
    ("check-size-1e300", ["check", "{D}/size_1e300.json"], 2, "edges must lie in"),
    ("check-size-1e-300-pybullet", ["check", "{D}/size_1e-300.json", "--engine", "pybullet"],
     2, "edges must lie in"),
    ("check-density-1e-300-pybullet",
     ["check", "{D}/density_1e-300.json", "--engine", "pybullet"], 2, "density: must lie in"),
    ("check-density-1e300", ["check", "{D}/density_1e300.json"], 2, "density: must lie in"),
    ("check-dev-zero", ["check", "{ZERO}"], 2, "is a device"),
    ("check-fifo", ["check", "{FIFO}"], 2, "is a named pipe"),
    ("check-folder-no-arrangements", ["check", "{FOREIGN}"], 2, "no arrangement files found"),
    ("check-bulk-missing", ["check", S, "{T}/missing.json"], 2, "no such file or folder"),
    ("check-missing", ["check", "{T}/missing.json"], 2, "no such file"),
    ("check-not-json", ["check", "{D}/pcd_size_short.pcd"], 2, "not"),
    ("check-threshold-negative", ["check", S, "--threshold", "-1"], 2, "--threshold"),
    ("check-threshold-nan", ["check", S, "--threshold", "nan"], 2, "--threshold"),
    ("check-mu-negative", ["check", S, "--mu", "-1"], 2, "--mu"),
    ("check-mu-huge", ["check", S, "--mu", "1e9"], 2, "--mu"),
    ("check-engine-budget-zero", ["check", S, "--engine-budget", "0"], 2, "--engine-budget"),
    ("check-unknown-engine", ["check", S, "--engine", "bullet"], 2, "--engine"),
    ("check-fixed-5m-apart", ["check", "{D}/fixed_5m_apart.json"], 2, "do not touch"),
    ("check-engine-over-budget", ["check", S, "--engine", "mujoco", "--engine-budget", "1e-4"],
     2, "would take about"),
    ("check-mujoco-cannot-load", ["check", "{D}/grain_on_a_cube.json", "--engine", "mujoco"],
     2, "mujoco cannot load this scene"),
    ("check-edges-1e6-apart", ["check", "{D}/dust_on_a_cube.json", "--engine", "all"], 2,
     "the engines cannot simulate edges from"),
    # ---- export
    ("export-id-nul", ["export", "{D}/id_nul.json", "--out", "{T}/x"], 2, "U+0000"),
    ("export-fixed-5m-apart", ["export", "{D}/fixed_5m_apart.json", "--out", "{T}/x"], 2,
     "do not touch"),
    ("export-out-proc", ["export", S, "--out", "/proc/x"], 2, "/proc"),
    ("export-out-empty", ["export", S, "--out", ""], 2, "empty path"),
    ("export-out-file", ["export", S, "--out", "{FILE}"], 2, "not a folder"),
    ("export-out-under-file", ["export", S, "--out", "{FILE}/x"], 2, "not a folder"),
    ("export-out-foreign", ["export", S, "--out", "{FOREIGN}"], 2, "did not write"),
    ("export-out-holds-input", ["export", S, "--out", "{D}"], 2, "contains the input"),
    ("export-mu-negative", ["export", S, "--out", "{T}/x", "--mu", "-1"], 2, "--mu"),
    ("export-dev-zero", ["export", "{ZERO}", "--out", "{T}/x"], 2, "is a device"),
    # ---- run: validated before any work
    ("run-seed-negative", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--seed", "-1"],
     2, "--seed"),
    ("run-out-empty", ["run", "{D}/identical_points.ply", "--out", ""], 2, "empty path"),
    ("run-out-proc", ["run", "{D}/identical_points.ply", "--out", "/proc/x"], 2, "/proc"),
    ("run-out-file", ["run", "{D}/identical_points.ply", "--out", "{FILE}"], 2, "not a folder"),
    ("run-mu-negative", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--mu", "-1"],
     2, "--mu"),
    ("run-cell-zero", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--cell", "0"],
     2, "--cell"),
    ("run-cell-negative", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--cell", "-1"],
     2, "--cell"),
    ("run-cell-ten", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--cell", "10"],
     2, "--cell"),
    ("run-budget-negative", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--budget",
                             "-5"], 2, "--budget"),
    ("run-max-depth-zero", ["run", "{D}", "--out", "{T}/r", "--max-depth", "0"], 2,
     "--max-depth"),
    ("run-scale-negative", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--scale",
                            "-1"], 2, "--scale"),
    ("run-depth-missing", ["run", "{D}", "--out", "{T}/r", "--depth", "nope.png"], 2,
     "--depth nope.png"),
    ("run-identical-points", ["run", "{D}/identical_points.ply", "--out", "{T}/r"], 2,
     "coincide"),
    ("run-pcd-size-short", ["run", "{D}/pcd_size_short.pcd", "--out", "{T}/r"], 2,
     "SIZE has 2 entries"),
    ("run-pcd-claims-4GB", ["run", "{D}/pcd_claims_4GB.pcd", "--out", "{T}/r"], 2, "claims"),
    ("run-dev-zero", ["run", "{ZERO}", "--out", "{T}/r"], 2, "is a device"),
    ("run-fifo", ["run", "{FIFO}", "--out", "{T}/r"], 2, "is a named pipe"),
    ("run-seed-not-int", ["run", "{D}", "--out", "{T}/r", "--seed", "x"], 2, "--seed"),
    ("run-seed-23-digits", ["run", "{D}/identical_points.ply", "--out", "{T}/r", "--seed",
                            "99999999999999999999999"], 2, "from 0 to 9223372036854775807"),
    ("run-intrinsics-three-numbers-cloud", ["run", "{D}/identical_points.ply", "--out", "{T}/r",
                                            "--intrinsics", "1,2,3"], 2, "4 finite numbers"),
    ("run-npz-without-pc", ["run", "{D}/two_arrays.npz", "--out", "{T}/r"], 2,
     "no array 'pc' (N x 3 or N x 6 points) among 'a', 'b'"),
    ("run-cloud-1e30-units", ["run", "{D}/cloud_1e30_units.ply", "--out", "{T}/r"], 2,
     "no unit from 1e-06 to 1e+06 m"),
    # ---- import: never over a user's file; numbers MuJoCo would only warn about
    ("import-over-a-foreign-file", ["import", "{D}/two_boxes.xml", "--out", "{FILE}"], 2,
     "exists and is not an arrangement file"),
    ("import-nan-position", ["import", "{D}/box_nan.xml", "--out", "{T}/a.json"], 2,
     "pos='nan 0 0.5' holds NaN or infinity"),
    # ---- the top level
    ("unknown-command", ["bogus"], 2, "unknown command 'bogus'"),
    # ---- demo, synth
    ("demo-seed-negative", ["demo", "--out", "{T}/d", "--seed", "-1"], 2, "--seed"),
    ("demo-budget-negative", ["demo", "--out", "{T}/d", "--budget", "-5"], 2, "--budget"),
    ("demo-out-file", ["demo", "--out", "{FILE}"], 2, "not a folder"),
    ("demo-family-unknown", ["demo", "--out", "{T}/d", "--family", "castle"], 2, "--family"),
    ("synth-views-1000", ["synth", "demo", "--out", "{T}/s", "--views", "1000"], 2,
     "would need about 25.0 GB"),
    ("synth-views-zero", ["synth", "demo", "--out", "{T}/s", "--views", "0"], 2, "--views"),
    ("synth-seed-negative", ["synth", "demo", "--out", "{T}/s", "--seed", "-1"], 2, "--seed"),
    ("synth-seed-23-digits", ["synth", "demo", "--out", "{T}/s", "--seed",
                              "99999999999999999999999"], 2, "--seed"),
    ("synth-out-proc", ["synth", "demo", "--out", "/proc/x"], 2, "/proc"),
    ("synth-n-boxes-huge", ["synth", "stack", "--out", "{T}/s", "--n-boxes", "1000000"], 2,
     "--n-boxes"),
    ("bench-out-proc", ["bench", "--out", "/proc/x", "--quick"], 2, "/proc"),
    # ---- score
    ("score-dev-zero", ["score", "{ZERO}", S], 2, "is a device"),
    ("score-fifo-truth", ["score", S, "{FIFO}"], 2, "is a named pipe"),
    ("score-truth-without-cuboids", ["score", S, "{D}/no_cuboids.json"], 2, "no cuboids"),
    # ---- eval
    ("eval-dask-not-an-address", ["eval", "regression", "--out", "{T}/e", "--dask",
                                  "notanaddress"], 2, "tcp://HOST:PORT"),
    ("eval-dask-nobody-there", ["eval", "regression", "--out", "{T}/e", "--dask",
                                "tcp://127.0.0.1:1"], 2, "no scheduler answers"),
    ("eval-unknown-case", ["eval", "regression", "--out", "{T}/e", "--only", "nosuchcase"],
     2, "unknown case"),
    ("eval-unknown-suite", ["eval", "table9", "--out", "{T}/e"], 2, "unknown suite"),
    ("eval-seed-negative", ["eval", "regression", "--out", "{T}/e", "--seed", "-1"], 2,
     "--seed"),
    ("eval-out-foreign", ["eval", "table1", "--out", "{FOREIGN}"], 2,
     "did not write (no command.json)"),
    ("eval-n-23-digits", ["eval", "regression", "--out", "{T}/e", "--n",
                          "99999999999999999999999"], 2, "--n: must be from 1 to"),
    ("eval-pool-first-seed-23-digits", ["eval", "pool", "--out", "{T}/e", "--first-seed",
                                        "99999999999999999999999"], 2, "--first-seed"),
    ("bench-out-foreign", ["bench", "--quick", "--out", "{FOREIGN}"], 2, "(no bench.md)"),
    ("bench-only-empty", ["bench", "--quick", "--only", "", "--out", "{T}/b"], 2,
     "--only: unknown section(s) (none given)"),
    # ---- models, dataset
    ("models-seed-negative", ["models", "make", "--out", "{T}/m", "--seed", "-1"], 2,
     "--seed"),
    ("models-kinds-empty", ["models", "make", "--out", "{T}/m", "--kinds", ""], 2, "--kinds"),
    ("dataset-first-seed-23-digits", ["dataset", "make", "--out", "{T}/d", "--n", "1",
                                      "--first-seed", "99999999999999999999999"], 2,
     "--first-seed"),
]
