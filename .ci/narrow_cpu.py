"""Print the NPY_DISABLE_CPU_FEATURES value that narrows numpy's run-time CPU
dispatch to its baseline, after proving in a child process that it changes
the kernels (bit patterns of exp/log/arctan/... results differ).

Exit status 0 with the value on stdout; 0 with an empty line when this CPU
offers nothing above numpy's baseline (nothing to narrow); 1 when the variable
is not honoured (the dispatch stays the same, or the results do not change).
"""

import json
import os
import subprocess
import sys

PROBE = r"""
import hashlib, json
import numpy as np
try:
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
except ImportError:  # numpy < 2
    from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
x = np.random.default_rng(0).uniform(-20.0, 20.0, 100_000)
a = np.abs(x) + 0.5
fns = {"exp": np.exp(x), "log": np.log(a), "arctan": np.arctan(x), "tan": np.tan(x),
       "arcsin": np.arcsin(x / 20.0), "expm1": np.expm1(x), "log1p": np.log1p(a),
       "power": np.power(a, x / 3.0), "sin32": np.sin(x.astype(np.float32))}
print(json.dumps({"dispatch": [d for d in __cpu_dispatch__ if __cpu_features__.get(d)],
                  "hash": {k: hashlib.sha1(v.tobytes()).hexdigest() for k, v in fns.items()},
                  "numpy": np.__version__}))
"""


def probe(env_value: str | None) -> dict:
    env = dict(os.environ)
    env.pop("NPY_DISABLE_CPU_FEATURES", None)
    if env_value:
        env["NPY_DISABLE_CPU_FEATURES"] = env_value
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def main() -> int:
    wide = probe(None)
    if not wide["dispatch"]:
        print("")
        print("ci: this CPU has no dispatch target above numpy's baseline", file=sys.stderr)
        return 0
    value = " ".join(wide["dispatch"])
    narrow = probe(value)
    changed = sorted(k for k in wide["hash"] if wide["hash"][k] != narrow["hash"][k])
    if narrow["dispatch"] or not changed:
        print(f"ci: NPY_DISABLE_CPU_FEATURES='{value}' is not honoured by numpy "
              f"{wide['numpy']}: dispatch {narrow['dispatch']}, changed kernels {changed}",
              file=sys.stderr)
        return 1
    print(f"ci: numpy {wide['numpy']}: disabling {value} changes the results of "
          f"{', '.join(changed)}", file=sys.stderr)
    print(value)
    return 0


if __name__ == "__main__":
    sys.exit(main())
