"""The help text of the ``pipegen`` command: the examples of each built-in subcommand (all of
them, in order, close ``pipegen --help``) and the notes on output folders and on what a technique
will not render of a scene, and on ``pipegen test``'s exit status."""

EXAMPLES = {
    "compile": """\
  pipegen compile pipelines/lidr_bitplanes.pipe -o build/lidr
      GLSL + pipeline_gl.py, OpenCL C + pipeline_cl.py, and report.txt in build/lidr/
  pipegen compile pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080 -o build/inferred
      with a parameter overridden; the report's memory figures at 1920x1080
  pipegen compile pipelines/inferred.pipe --scene examples/scenes/small.toml -o build/inferred-small
      specialised for the scene's features; report.txt says what was culled and why
  pipegen compile pipelines/forward.pipe --dump-after fold -o build/forward
      the IR after the fold pass, in .pipe spelling, on stdout (all: after every pass)
""",
    "run": """\
  pipegen run pipelines/forward.pipe -o out/forward
      render the built-in default scene: one PNG and one .npy per target
  pipegen run pipelines/deferred.pipe --scene examples/scenes/many_lights.toml --size 640x360 -o out/deferred
  pipegen run pipelines/forward.pipe --backend cl -o out/forward-cl
      the same technique on the PoCL software reference
  pipegen run pipelines/inferred.pipe -p lbuffer_scale=0.5 -o out/inferred
  pipegen run pipelines/lidr_bitplanes.pipe --scene examples/scenes/mixed_lights.toml --strict -o out/lidr
      exit 1, listing what the technique will not render of this scene (a warning without --strict)
  pipegen run pipelines/deferred_calver.pipe --scene examples/scenes/small.toml --general -o out/calver
      render the general build: every pass and target, not the variant compiled for the scene
""",
    "check": """\
  pipegen check pipelines/lidr_bitplanes.pipe
      GL vs CL on the built-in scene, one row per target; error images in build/check/lidr_bitplanes/
  pipegen check pipelines/lidr_max_stencil.pipe --scene examples/scenes/stress_overlap.toml
      exit 1 and the first divergent pass on disagreement
  pipegen check pipelines/inferred.pipe --scene examples/scenes/small.toml --general
      GL vs CL on the general build instead of the variant compiled for the scene
""",
    "info": """\
  pipegen info pipelines/inferred.pipe
      parameters, targets (bytes at 1280x720), passes and packing schemes
  pipegen info pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080
""",
    "specialise": """\
  pipegen specialise pipelines/inferred.pipe --scene examples/scenes/small.toml
      the scene's features, what is culled and why, passes and targets before and after
  pipegen specialise pipelines/deferred_calver.pipe --scene examples/scenes/small.toml --verify
      render general and specialised on GL and CL, compare bit for bit (exit 1 if they differ)
""",
    "graph": """\
  pipegen graph pipelines/deferred.pipe -o deferred.svg
      passes, targets and their read/write/depth edges (an SVG with Graphviz, else DOT text)
  pipegen graph pipelines/inferred.pipe --scene examples/scenes/small.toml -o inferred.svg
      culled passes and targets greyed, each with its reason
""",
    "test": """\
  pipegen test stripes.pipe
      one line per `expect` of the file: ok, or FAILED with the numbers
  pipegen test techniques/*.pipe -p steps=4
      every file's expectations, with a parameter overridden in each
""",
}

OUTPUT_NOTE = """\
output folders (-o): created if missing; pipegen writes a manifest (.pipegen-manifest.json) of
the files it wrote, replaces only those on the next run, and never deletes or overwrites a file
it did not write.  A non-empty folder it did not write is refused unless --force.
"""

MISMATCH_NOTE = """\
what a technique will not render of a scene (a light type it cannot draw, translucent objects
it never draws, more lights per pixel than its packing holds) is printed as a warning before
rendering; --strict makes it an error (exit 1).
"""


TEST_NOTE = """\
exit status: 0 when every expectation holds; 1 when one fails (each named with its file:line),
when a file has an error, or when no FILE has an expectation (a file without any is listed as
such and does not fail the run by itself); 2 for misuse of the command line.
"""
