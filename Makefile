.PHONY: setup demo test bench clean
setup:
	bash scripts/setup.sh
demo: setup
	. .venv/bin/activate && MPLBACKEND=Agg hexapod-demo --out demo_out
test:
	bash scripts/test.sh
bench: setup
	. .venv/bin/activate && for b in bench/bench_*.py; do echo "== $$b"; python $$b || exit 1; done
clean:
	rm -rf build install log demo_out
