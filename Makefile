# The two set-up commands are `make demo` and `make test`: each creates .venv itself.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench firmware system-deps clean venv

# Debian packages the project runs against for real: espeak-ng (voice), the AVR
# toolchain and simavr (the belt firmware on a simulated ATmega328P; gcc builds
# its harness against libsimavr), systemd
# (systemd-analyze verify on the units). Installed only when one is missing.
DEBIAN_PACKAGES := espeak-ng gcc-avr avr-libc binutils-avr simavr libsimavr-dev libsimavrparts1 libelf-dev pkg-config gcc libc6-dev systemd strace
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

system-deps:
	@missing=$$(for p in $(DEBIAN_PACKAGES); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing Debian packages:" $$missing; \
		$(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	fi

demo: $(STAMP) system-deps
	$(BIN)/guidebelt demo

test: $(STAMP) system-deps
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q

# The belt firmware (ELF + HEX for the Nano) and its simavr harness, in build/belt/.
firmware: system-deps
	$(MAKE) -C drivers/belt/firmware BUILD=$(CURDIR)/build/belt

lint: $(STAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/guidebelt bench --grid 100,200,400 --unknown 0.2,0.4,0.6 --backend cpu --json bench.json

clean:
	rm -rf $(VENV) build *.egg-info
