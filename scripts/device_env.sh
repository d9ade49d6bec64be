# Sourced by scripts/gpu_check.sh from the repository root: the environment its Python runs in
# on the GPU machine.
export PYTHONUNBUFFERED=1
# typer and rich for the CLI: the image has them; else the wheels carried in .whl/ go into
# $CLI_SITE, for the caller to put on PYTHONPATH.
CLI_SITE=
if ! python3 -c "import typer, rich" 2>/dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl && CLI_SITE=/tmp/site
fi
