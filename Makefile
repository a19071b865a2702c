# odocal: `make demo` runs the whole synthetic experiment, `make test` the tests.
# Both first install the Debian packages the build needs (idempotent).

SHELL := /bin/bash
APT_PACKAGES := libopencv-dev clang libclang-dev pkg-config chromium ffmpeg
CARGO ?= cargo
DEMO_OUT ?= demo-out

.PHONY: deps build demo test lint bench clean

deps:
	@./scripts/install-deps.sh $(APT_PACKAGES)

build: deps
	$(CARGO) build --release

# The build is timed too: the demo's summary reports it with the stages.
demo: deps
	@start=$$(date +%s); $(CARGO) build --release && \
	  DEMO_BUILD_S=$$(( $$(date +%s) - start )) ./scripts/demo.sh $(DEMO_OUT)

test: deps
	$(CARGO) test --workspace

lint: deps
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings

bench: deps
	$(CARGO) bench

clean:
	$(CARGO) clean
	rm -rf $(DEMO_OUT)
