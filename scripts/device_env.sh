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

# The device checks' steps: `step NAME SECONDS COMMAND...` runs COMMAND with a time limit, logs
# it to $OUT/NAME.log, notes its exit status in $OUT/steps.txt (124: past its limit) and sets
# fail=1 when it failed; the caller sets OUT and fail.
step() {
    local name=$1 limit=$2
    shift 2
    echo "== $name: $*"
    local t0=$SECONDS
    timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
    local rc=$?
    [ "$rc" -eq 0 ] || fail=1
    echo "$name rc=$rc $((SECONDS - t0))s" >>"$OUT/steps.txt"
    tail -n 2 "$OUT/$name.log"
    echo "   rc=$rc in $((SECONDS - t0)) s"
}
