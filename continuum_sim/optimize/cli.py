"""``continuum-sim optimize SPEC.toml``: search the design space for the best (robust) designs;
``continuum-sim evaluate DESIGN.toml``: one design evaluated as its study evaluated it."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

EXIT_NEGATIVE = 1  # the command ran but the answer is no (docs/errors.md): not reproduced, or every evaluation failed


def cmd_optimize(args: argparse.Namespace) -> int:
    from ..configio import check_output_dir
    from .spec import load_spec, with_optimizer
    from .study import run_study

    spec = with_optimizer(load_spec(args.spec), trials=args.trials, seed=args.seed)
    out = Path(args.out) if args.out else Path("runs/optimize") / Path(args.spec).stem
    check_output_dir(out, create=False)
    try:
        result = run_study(spec, out, workers=args.workers, backend=args.backend, address=args.address, progress=not args.quiet,
                           spec_path=args.spec, storage=args.storage, study_name=args.study_name)
    except KeyboardInterrupt:
        print(f"continuum-sim optimize: interrupted; told trials and finished evaluations are kept in {out}, rerun to resume",
              file=sys.stderr)
        return 130
    summary = result.summary
    print(f"{result.root}: {spec.optimizer.sampler}, {result.n_trials} designs ({summary['states']['FAIL']} failed, "
          f"{summary['feasible']} feasible); this run: {result.n_evaluated} evaluations, {result.n_reused} reused, "
          f"{result.n_resumed} interrupted designs re-run; CPU {summary['cpu_s']:.0f} s in all")
    if not args.quiet:
        for best in summary["best"][:10]:
            values = ", ".join(f"{k} {v:.4g}" for k, v in best["values"].items())
            params = ", ".join(f"{k} = {v:.4g}" for k, v in best["params"].items())
            print(f"  trial {best['trial']}: {values} | {params} -> {best['config']}")
        optuna = summary["optuna"]
        print(f"  report: summary.json, trials.csv, pareto.csv, plots/, best/*.toml (continuum-sim run --config; "
              f"continuum-sim evaluate); Optuna study {optuna['study_name']!r} in {optuna['storage']}")
        for note in summary.get("notes", []):
            print(f"  note: {note}")
    return 0


def add_optimize_parser(sub: Any) -> None:
    """Register ``optimize`` on the CLI's subparsers."""
    p = sub.add_parser("optimize", help="design optimisation (Optuna: NSGA-II, TPE, CMA-ES), robust to assumed parameters; resumable")
    p.add_argument("spec", metavar="SPEC.toml", help="study spec: variables, objectives, constraints, robustness (docs/optimize.md)")
    p.add_argument("--out", help="study folder (default: runs/optimize/<spec name>); rerun to resume")
    p.add_argument("--trials", type=int, metavar="N", help="designs to evaluate (default: the spec's optimizer.trials); "
                                                          "rerun with a larger N to extend a study")
    p.add_argument("--seed", type=int, metavar="S", help="sampler seed (default: the spec's optimizer.seed); another seed is another study")
    p.add_argument("--storage", metavar="URL", help="Optuna storage (default: the journal file OUT/study.journal), e.g. "
                                                    "sqlite:///studies.db or postgresql://user@host/db; optuna-dashboard reads it")
    p.add_argument("--study-name", metavar="NAME", help="the study's name in the storage (default: optimize in the folder's journal, "
                                                        "the folder's name in another storage)")
    p.add_argument("--workers", type=int, help="parallel workers (default: all cores; Ray: cluster CPUs)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="where evaluations run (default: local)")
    p.add_argument("--address", help="Ray cluster address (--backend ray; default: start a local one)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or best designs")
    p.set_defaults(func=cmd_optimize)


# ------------------------------------------------------------------------ evaluate
def _evaluation_option(text: str, recorded: Any) -> Any:
    """``--evaluation``: a kind (the recorded evaluation's own settings when it is of that kind) or a JSON table."""
    from ..configio import ConfigError
    from ..sweep.evaluations import parse_evaluation

    if text.lstrip().startswith("{"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ConfigError("--evaluation", f"not a JSON table ({exc.msg}); give a kind or e.g. '{{\"kind\": \"gravity_sag\", \"settle_s\": 0.5}}'") from None
        return parse_evaluation(data)
    if recorded is not None and recorded.kind == text:
        return recorded
    return parse_evaluation({"kind": text})


def evaluate_file(design: str | Path, evaluation: str | None = None, spec_path: str | Path | None = None) -> dict[str, Any]:
    """Evaluate the design TOML ``design`` as its study did; the objective values, the recorded ones, whether they are equal.

    The evaluation, objectives, constraints and robustness samples come from ``spec_path`` (a
    study spec) or else from the design's header (``design.header_lines``); ``evaluation`` (a
    kind or a JSON table) replaces the evaluation. ``ConfigError`` naming the option when
    nothing says how to evaluate.
    """
    import dataclasses

    from ..configio import ConfigError, read_config_text
    from ..scenario.config import ScenarioConfig
    from ..sweep.evaluations import parse_evaluation
    from .design import check_config, header_spec, read_header, robustness_samples
    from .spec import SUCCESS, Optimizer, OptimizeSpec, Robustness, load_spec
    from .study import evaluate_design

    path = Path(design)
    header = read_header(read_config_text(path))
    config = ScenarioConfig.from_toml(path)
    recorded = None
    spec: OptimizeSpec | None = None
    samples: list[Any] = [()]
    if spec_path is not None:
        study = load_spec(spec_path)
        spec = dataclasses.replace(study, base=config)
        samples = robustness_samples(study) if study.robust else [()]
    elif header is not None:
        try:
            spec, samples = header_spec(config, header, parse_evaluation(header["evaluation"]))
        except ConfigError as exc:
            raise exc.under(f"{path}: ") from None
    if header is not None and spec is not None and header["evaluation"] == spec.evaluation.to_dict():
        recorded = header.get("values")
    if evaluation is not None:
        chosen = _evaluation_option(evaluation, None if spec is None else spec.evaluation)
        if spec is None:
            spec = OptimizeSpec(config, (), (), (), Robustness(), Optimizer(), chosen)
        elif chosen != spec.evaluation:  # another evaluation: nothing to compare with; the objectives it does not measure dropped
            known = chosen.known_metrics()
            keep = [o for o in spec.objectives if known is None or o.metric in known or o.metric == SUCCESS]
            bounds = [c for c in spec.constraints if known is None or c.metric in known]
            spec, recorded = dataclasses.replace(spec, evaluation=chosen, objectives=tuple(keep), constraints=tuple(bounds)), None
    if spec is None:
        raise ConfigError("--evaluation", f"{path} has no study header; name the evaluation (scenario | stage | gravity_sag | "
                                          "tip_deflection, or a JSON table) or give the study's --spec")
    for sample in samples:
        check_config(spec, sample)  # the design (and each sample) must suit the evaluation: one line, exit 2
    records, outcome = evaluate_design(spec, config, samples)
    labels = [o.label for o in spec.objectives]
    values = None if outcome["values"] is None else dict(zip(labels, outcome["values"]))
    equal = None
    if recorded is not None and labels:
        equal = values is not None and all(values.get(k) == v for k, v in recorded.items()) and set(values) == set(recorded)
    return {
        "design": str(path),
        "evaluation": spec.evaluation.to_dict(),
        "samples": len(samples),
        "objectives": values,
        "recorded": recorded,
        "equal": equal,
        "success_probability": outcome["success_probability"] if spec.robust else None,
        "failure": outcome.get("failure"),
        "failures": outcome["failures"],
        "evaluations_failed": sum(r["status"] != "ok" for r in records),
        "metrics": [r["metrics"] for r in records],
        "study": None if header is None else {k: header.get(k) for k in ("study", "trial", "spec_sha256", "commit", "dirty")},
    }


def cmd_evaluate(args: argparse.Namespace) -> int:
    from .study import SUCCESS

    out = evaluate_file(args.design, args.evaluation, args.spec)
    if args.json:
        print(json.dumps(out, indent=1, sort_keys=True))
    else:
        kind = out["evaluation"]["kind"]
        study = out["study"] or {}
        origin = f"trial {study['trial']} of {study['study']}" if study.get("study") else "no study header"
        print(f"{out['design']}: {kind}, {out['samples']} evaluation{'s' if out['samples'] != 1 else ''} ({origin})")
        if out["objectives"] is None:
            print(f"  no objective values: {out['failure']}")
        if out["objectives"]:
            for label, value in out["objectives"].items():
                before = (out["recorded"] or {}).get(label)
                mark = "" if before is None else f"   (recorded {before!r}: {'equal' if before == value else 'DIFFERENT'})"
                print(f"  {label} = {value!r}{mark}")
            if out["success_probability"] is not None:
                print(f"  {SUCCESS} = {out['success_probability']!r}")
        else:  # no objectives to show (none asked, or not measured by this evaluation): the metrics
            for k, metrics in enumerate(out["metrics"]):
                prefix = f"sample {k}: " if len(out["metrics"]) > 1 else ""
                for name, value in metrics.items():
                    print(f"  {prefix}{name} = {value!r}")
        if out["equal"] is True:
            print("reproduced: every objective equals the recorded value exactly")
        elif out["equal"] is False:
            print("NOT reproduced: an objective differs from the recorded value (code, libraries or machine changed?)")
    failed = out["evaluations_failed"] == out["samples"]
    if failed:
        print(f"continuum-sim evaluate: the evaluation failed: {'; '.join(out['failures'])}", file=sys.stderr)
    return EXIT_NEGATIVE if out["equal"] is False or failed else 0


def add_evaluate_parser(sub: Any) -> None:
    """Register ``evaluate`` on the CLI's subparsers."""
    p = sub.add_parser("evaluate", help="evaluate one design (a study's best/trial_<n>.toml) as its study did; "
                                        "exit 1 when the objectives differ from the recorded ones")
    p.add_argument("design", metavar="DESIGN.toml", help="a scenario TOML; a best design's header names its evaluation and objectives")
    p.add_argument("--evaluation", metavar="KIND", help="scenario | stage | gravity_sag | tip_deflection, or a JSON table "
                                                        "(default: the design's header, or the --spec's)")
    p.add_argument("--spec", metavar="SPEC.toml", help="the study spec whose evaluation, objectives and robustness samples to use "
                                                       "(default: the design's header)")
    p.add_argument("--json", action="store_true", help="print JSON (objectives, recorded values, metrics per evaluation)")
    p.set_defaults(func=cmd_evaluate)
