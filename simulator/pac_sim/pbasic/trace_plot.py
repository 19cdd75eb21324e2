"""Plot a servo trace: the pulse width each servo received over time, one row per pin (PNG).

A gap in a row is an activation in which that servo got no pulse (the affecter's dragging
hips, for instance). Usage, e.g. one gait cycle of the firmware's gait id 3::

    python -m pac_sim.pbasic.trace_plot firmware/servobot.bs2 --label GaitCycle \\
        --set gid=3 --out docs/img/firmware_gait_cycle_3.png
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import click
import matplotlib

from .peripherals import Pulse

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402 - after choosing the non-interactive backend


def plot_pulses(pulses: Sequence[Pulse], out: str | Path, title: str = "") -> Path:
    """Write a PNG with one row per pin: width (us) against Stamp time (ms)."""
    if not pulses:
        raise ValueError("no pulses to plot")
    pins = sorted({p.pin for p in pulses})
    t0 = min(p.t_us for p in pulses)
    fig, axes = plt.subplots(len(pins), 1, sharex=True, figsize=(9, 1.0 + 0.75 * len(pins)),
                             squeeze=False)
    by_pin = {pin: [p for p in pulses if p.pin == pin] for pin in pins}
    busiest = max(by_pin.values(), key=len)
    steps = sorted(b.t_us - a.t_us for a, b in zip(busiest, busiest[1:], strict=False))
    gap = 1.5 * steps[len(steps) // 2] if steps else float("inf")
    for ax, pin in zip(axes[:, 0], pins, strict=True):
        mine = by_pin[pin]
        xs: list[float] = []
        ys: list[float] = []
        for i, p in enumerate(mine):
            if i and p.t_us - mine[i - 1].t_us > gap:  # missed activations: break the line
                xs.append(float("nan"))
                ys.append(float("nan"))
            xs.append((p.t_us - t0) / 1000)
            ys.append(2 * p.width)
        ax.plot(xs, ys, ".-", ms=3, lw=0.8)
        ax.set_ylabel(f"pin {pin}\n({len(mine)})", rotation=0, ha="right", va="center", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("Stamp time (ms); row label: pin (pulses); y: pulse width (us)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


@click.command()
@click.argument("source", type=click.Path(exists=True, dir_okay=False))
@click.option("--label", required=True, help="subroutine to run (it must RETURN)")
@click.option("--set", "sets", multiple=True, help="variable=value before the call")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def main(source: str, label: str, sets: tuple[str, ...], out: str) -> None:
    """Run one subroutine of SOURCE in the interpreter and plot its servo trace."""
    from pac_host.errors import PacError

    from .machine import Stamp

    variables = {}
    for item in sets:
        name, _, value = item.partition("=")
        try:
            variables[name] = _number(value)
        except ValueError:
            raise click.BadParameter(f"{item!r} is not variable=value", param_hint="--set") \
                from None
    try:
        stamp = Stamp.from_file(source)
        stamp.call(label, **variables)
    except (PacError, KeyError, RuntimeError) as e:
        err = click.ClickException(str(e).strip("'\""))
        err.exit_code = getattr(e, "exit_code", 1)
        raise err from None
    shown = ", ".join(sets)
    plot_pulses(stamp.servo.pulses, out, f"{Path(source).name}: {label} ({shown})")


def _number(text: str) -> int:
    """A PBASIC-style number: decimal, $hex or %binary."""
    if text.startswith("$"):
        return int(text[1:], 16)
    if text.startswith("%"):
        return int(text[1:], 2)
    return int(text, 10)


if __name__ == "__main__":
    main()
