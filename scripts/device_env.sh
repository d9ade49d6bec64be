# Sourced by scripts/gpu_check.sh from the repository root: the environment its Python runs in
# on the GPU machine.
export PYTHONUNBUFFERED=1
# The GPU image has numpy, numba, cupy, typer and rich but not pydantic or zenoh, which the
# navigator (and so the benchmark) and the protocol need: their wheels, carried in .whl/ (fetch
# them with `pip download --only-binary=:all: --python-version 3.12 --platform
# manylinux2014_x86_64 -d .whl pydantic eclipse-zenoh`), go into $CLI_SITE for the caller to put
# on PYTHONPATH.
CLI_SITE=
if ! python3 -c "import typer, rich, pydantic, zenoh" 2>/dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl && CLI_SITE=/tmp/site
fi
