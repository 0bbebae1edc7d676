"""Property-based fuzzing of every untrusted input (tests/fuzzing.py holds the
targets, tests/fuzz_models.py the models'): exemplar images, project and
autosave files, command lines, the working folders of resumable exports
(OUT.parts, tampered with), model files (OBJ, glTF, GLB). Each
input must be accepted with a valid result or refused with the program's own
one-line error: no other exception, no hang, no subprocess, no read outside
what the user chose, no damaged or replaced file.

The "ci" profile runs 200 fixed cases per target; ``pytest tests/reliability/test_fuzz.py
--hypothesis-profile=long`` runs 10,000 random ones (see bench/fuzz.py for the
figures with counts, timings and memory)."""
import shutil

import numpy as np
import pytest
from hypothesis import given

import fuzz_models as FM
import fuzzing as F


@pytest.fixture(scope="module")
def project_root():
    root = F.project_sandbox()
    yield root
    shutil.rmtree(F.os.path.dirname(root), ignore_errors=True)


@pytest.fixture(scope="module")
def cli_root():
    root = F.cli_sandbox()
    yield root
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def parts_root():
    root = F.parts_sandbox()
    yield root
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def model_root():
    root = FM.model_sandbox()
    yield root
    shutil.rmtree(root, ignore_errors=True)


@given(case=FM.model_cases())
def test_fuzz_model_files(model_root, case):
    """OBJ (with its .mtl and texture), glTF (with its buffers) and GLB files,
    mutated, with hostile numbers and tampered references, loaded with and
    without --unwrap (tests/fuzz_models.py)."""
    FM.run_model(case, model_root)


def test_every_spelling_of_a_models_reference_goes_through_the_gate(model_root):
    """The spellings that once got past the model's checks (a commented mtllib,
    a folder that does not exist, an absolute path, MAP_KD, a space, a data: URI
    without base64, a NUL), each naming a FIFO, a character device, a link out
    or a plain file: no hang, no read outside, one line or a model whose inputs
    include every file read (tests/fuzz_models.py's seeds of the fuzz target)."""
    outcomes = {}
    for kind, spellings in FM.SPELLINGS.items():
        for spelling in spellings:
            for tamper in ("none", "fifo", "device", "link-out"):
                outcomes[kind, spelling, tamper] = FM.run_model(FM.spelling_case(kind, spelling, tamper), model_root,
                                                                timeout=20)
    # Where trimesh finds the file by its fallbacks, it is read (and an input); a data: URI is refused.
    assert outcomes["obj", "no-folder", "none"] == outcomes["obj", "spaced", "none"] == "accepted"
    assert outcomes["gltf", "absolute", "none"] == "accepted"
    assert outcomes["gltf", "data-uri", "none"] == "refused"
    # A FIFO or a device where the texture or buffer is found: refused, never opened for reading.
    assert outcomes["obj", "upper-key", "fifo"] == outcomes["gltf", "no-folder", "device"] == "refused"


def test_images_laid_out_in_many_pieces_are_bounded_from_their_headers():
    """The seeds of the image target's layouts: a 512^2 PNG of 1-byte IDAT
    chunks and a 4112^2 TIFF of 16 x 16 LZW tiles (66,049) are refused in one
    line within the time limit (each ran past 60 s under load); the same
    layouts at ordinary sizes are read."""
    from PIL import Image
    noise = Image.fromarray(np.random.default_rng(1).integers(0, 255, (512, 512), np.uint8))
    assert F.run_import(F.rechunk_png(F.encode(noise, "PNG", 0), 1), timeout=20) == "refused"
    big = Image.fromarray(np.zeros((4112, 4112), np.uint8))
    assert F.run_import(F.tiled_tiff(big, "lzw"), timeout=20) == "refused"
    small = noise.crop((0, 0, 64, 64))
    assert F.run_import(F.rechunk_png(F.encode(small, "PNG", 0), 7)) == "accepted"
    assert F.run_import(F.tiled_tiff(small, "lzw")) == "accepted"


@given(data=F.image_files())
def test_fuzz_exemplar_import(data):
    F.run_import(data)


@given(data=F.project_files())
def test_fuzz_project_and_autosave_files(project_root, data):
    F.run_project(data, project_root)


@given(argv=F.command_lines())
def test_fuzz_command_lines(cli_root, argv):
    F.run_cli(argv, cli_root)


@pytest.mark.slow
@given(case=F.parts_folders())
def test_fuzz_export_working_folders(parts_root, case):
    F.run_parts(case, parts_root)


def test_the_targets_reach_both_outcomes(project_root, cli_root, parts_root, model_root):
    """The generators are not degenerate: each target sees inputs it accepts and
    inputs it refuses (a fuzzer that only makes garbage tests nothing)."""
    import io

    from PIL import Image
    good = io.BytesIO()
    F.make_image("RGB", 64, 64, 1).save(good, "PNG")
    assert F.run_import(good.getvalue()) == "accepted"
    assert F.run_import(F.EPS_LOOP) == "refused"
    base = F.json.dumps(F.base_project()).encode()
    assert F.run_project(base, project_root) == "accepted"
    assert F.run_project(base[:-5], project_root) == "refused"
    assert F.run_cli(["synth", "TINY", "-o", "OUT.png", "--size", "40", "32"], cli_root) == "accepted"
    assert F.run_cli(["synth", "TINY", "-o", "out.xyz"], cli_root) == "refused"
    clean = dict(fmt="tiff", start="complete", parts="folder", tiles=["keep"] * 8, manifest="keep",
                 assembly="none", foreign="none", zarr="none", seed=0)
    assert F.run_parts(clean, parts_root) == "accepted"
    assert F.run_parts(dict(clean, parts="link-folder"), parts_root) == "refused"
    assert Image  # imported for the PNG above
    for kind in FM.KINDS:
        files = FM._bases()[kind]
        main = next(n for n in files if n.startswith("model."))
        others = sorted(n for n in files if n != main)
        case = dict(kind=kind, main=main, files=files, tamper="none", how="clean", victim=None, unwrap=True)
        assert FM.run_model(case, model_root) == "accepted"
        bad = dict(case, tamper="fifo", victim=others[0]) if others else dict(case, files={main: files[main][:40]})
        assert FM.run_model(bad, model_root) == "refused"
