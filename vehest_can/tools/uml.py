"""A real SocketCAN ``vcan0`` on a host kernel without CAN, via user-mode Linux (UML).

UML is a Linux kernel that runs as an ordinary host process. We boot it with the host's own ``/``
as its root file system (``hostfs``), so the guest runs the host's binaries, the project's venv
and the test files in place; the guest's kernel has CAN, so ``insmod`` of its ``can``,
``can-raw``, ``can-bcm``, ``can-dev`` and ``vcan`` modules gives a real ``vcan0`` (MTU 72: CAN FD)
for python-can's ``socketcan`` interface and can-utils.

Each :func:`run` boots a fresh guest (about 1-3 s), runs one shell command line as root with the
caller's working directory and environment, and powers off. The command's stdout, stderr and
exit status travel back as files in a host temporary directory, which the guest sees through
hostfs; the UML console (kernel log) goes to ``console.log`` beside them and is only read to
explain failures.

Limits: the guest kernel ticks at 100 Hz and shares the host CPU, so use it for functional
tests (frames, flags, interop), never for timing.

Which UML kernel: ``$VEHEST_UML_KERNEL`` if set, else one fetched by :func:`fetch_kernel` into
``$VEHEST_UML_HOME`` (default ``~/.cache/vehest-can/uml``), else Debian's ``user-mode-linux``
package (``/usr/bin/linux.uml``). Debian 12's UML 6.1 (and Debian 13's 6.12) panics at the
first guest process on hosts whose XSAVE area is larger than its fixed buffer (AVX-512/AMX CPUs:
"ptrace set fp regs failed, errno = 14"); newer UML kernels size it from the host, hence
:func:`fetch_kernel`. See ``docs/uml.md``.

Run by hand: ``vehest-can uml -- ip -details link show vcan0``.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

from vehest_can.errors import VehestError

__all__ = [
    "UmlError",
    "UmlTimeout",
    "UmlKernel",
    "UmlResult",
    "find_kernel",
    "available",
    "run",
    "fetch_kernel",
    "default_home",
    "CAN_MODULES",
    "CARRIED_ENV",
]

#: Kernel modules loaded in the guest (their dependencies, e.g. ``can-dev``, come along).
CAN_MODULES = ("can", "can-raw", "can-bcm", "vcan")

#: Loaded when the kernel has it: ``dummy`` gives the guest a multicast-capable interface,
#: ``mcast0``, so python-can's udp_multicast (IPv6 and IPv4 groups) works inside too.
OPTIONAL_MODULES = ("dummy",)

#: Host tools the guest uses from the shared root: ``insmod`` (kmod), ``ip`` (iproute2) and
#: can-utils.
GUEST_TOOLS = ("sh", "mount", "sync", "insmod", "ip", "candump", "cansend")

#: Host environment variables carried into the guest command (plus the ``env`` argument).
CARRIED_ENV = (
    "PATH", "PYTHONPATH", "VIRTUAL_ENV", "HOME", "USER", "LANG", "LC_ALL", "LC_CTYPE", "TZ",
    "PYTHONHASHSEED", "PYTHONDONTWRITEBYTECODE", "PYTHONUNBUFFERED", "CI",
)

#: Debian suites tried in turn by :func:`fetch_kernel` (a UML kernel >= 6.13 is needed on
#: AVX-512/AMX hosts; Debian 13 "trixie" ships 6.12).
FETCH_SUITES = ("testing", "unstable")

_IFACE_RE = re.compile(r"^[A-Za-z0-9_.-]{1,15}$")
_FP_BUG = "ptrace set fp regs failed"


class UmlError(VehestError):
    """User-mode Linux is missing, failed to boot, or failed to set up the guest.

    ``summary`` is the message without the console tail; ``workdir`` is where the run's files
    (init script, console.log, setup.log) were kept, if any.
    """

    def __init__(self, summary: str, *, console_tail: str = "", workdir: Path | None = None):
        message = summary
        if workdir is not None:
            message += f"\nFiles kept in {workdir}."
        if console_tail:
            message += f"\nConsole tail:\n{console_tail}"
        super().__init__(message)
        self.summary = summary
        self.console_tail = console_tail
        self.workdir = workdir


class UmlTimeout(UmlError, TimeoutError):
    """The guest did not finish within the timeout; its whole process tree was killed."""


@dataclasses.dataclass(frozen=True)
class UmlKernel:
    """A UML kernel binary and the module tree matching its version."""

    binary: Path
    modules: Path  # .../modules/<version>
    version: str
    origin: str  # "VEHEST_UML_KERNEL", "fetched" or "system"


@dataclasses.dataclass(frozen=True)
class UmlResult:
    """What one guest run produced."""

    returncode: int
    stdout: str
    stderr: str
    console: str  # the UML console (kernel log); noisy, for diagnosis
    console_log: Path | None  # kept only when run() was given a workdir
    boot_seconds: float  # host wall time from launch until the guest ran the command
    total_seconds: float  # host wall time from launch until the UML process exited


# --------------------------------------------------------------------------- kernel discovery


def default_home() -> Path:
    """Where :func:`fetch_kernel` puts a kernel: ``$VEHEST_UML_HOME`` or the user cache."""
    if os.environ.get("VEHEST_UML_HOME"):
        return Path(os.environ["VEHEST_UML_HOME"])
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(cache) / "vehest-can" / "uml"


def _kernel_version(binary: Path) -> str:
    """``linux --version`` prints the release without booting."""
    try:
        out = subprocess.run([str(binary), "--version"], capture_output=True, text=True,
                             timeout=20, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise UmlError(f"cannot run UML kernel {binary}: {exc}") from exc
    version = out.stdout.strip().splitlines()[-1:] if out.returncode == 0 else []
    if not version or not re.match(r"^\d+\.\d+", version[0]):
        raise UmlError(f"{binary} --version failed (exit {out.returncode}): "
                       f"{(out.stdout + out.stderr).strip()[-300:]}")
    return version[0].strip()


def _kernel_at(binary: Path, module_root: Path, origin: str) -> UmlKernel:
    version = _kernel_version(binary)
    modules = module_root / version
    if not (modules / "modules.dep").is_file():
        raise UmlError(f"no modules for UML {version} ({binary}): {modules}/modules.dep missing")
    return UmlKernel(binary=binary, modules=modules, version=version, origin=origin)


def _fetched_kernel(home: Path) -> UmlKernel | None:
    binary = home / "root" / "linux"
    if not binary.is_file():
        return None
    return _kernel_at(binary, home / "root" / "usr" / "lib" / "uml" / "modules", "fetched")


def find_kernel() -> UmlKernel:
    """The UML kernel to boot (see the module docstring for the order); raises UmlError."""
    explicit = os.environ.get("VEHEST_UML_KERNEL")
    if explicit:
        binary = Path(explicit)
        if not binary.is_file():
            raise UmlError(f"VEHEST_UML_KERNEL={explicit} is not a file")
        module_root = Path(os.environ.get("VEHEST_UML_MODULES")
                           or binary.resolve().parent.parent / "lib" / "uml" / "modules")
        return _kernel_at(binary, module_root, "VEHEST_UML_KERNEL")
    fetched = _fetched_kernel(default_home())
    if fetched is not None:
        return fetched
    for name in ("/usr/bin/linux.uml", "/usr/bin/linux"):
        if os.path.isfile(name) and os.access(name, os.X_OK):
            return _kernel_at(Path(name), Path("/usr/lib/uml/modules"), "system")
    raise UmlError("no UML kernel: apt-get install user-mode-linux, or "
                   "`vehest-can uml --fetch` (see docs/uml.md)")


def _module_plan(kernel: UmlKernel) -> list[Path]:
    """Absolute .ko paths for CAN_MODULES and their dependencies, dependencies first.

    Reads the kernel's own ``modules.dep``; modules built into the kernel are skipped.
    """
    def norm(path: str) -> str:
        return os.path.basename(path).split(".ko")[0].replace("_", "-")

    deps: dict[str, tuple[str, list[str]]] = {}
    for line in (kernel.modules / "modules.dep").read_text().splitlines():
        if ":" in line:
            mod, rest = line.split(":", 1)
            deps[norm(mod)] = (mod, rest.split())
    builtin_file = kernel.modules / "modules.builtin"
    builtin = ({norm(p) for p in builtin_file.read_text().split()}
               if builtin_file.is_file() else set())

    order: list[Path] = []

    def visit(name: str) -> None:
        if name in builtin:
            return
        if name not in deps:
            raise UmlError(f"UML {kernel.version} has no module {name} in {kernel.modules}")
        rel, needs = deps[name]
        for dep in needs:
            visit(norm(dep))
        path = kernel.modules / rel
        if path not in order:
            if not path.is_file():
                raise UmlError(f"module file missing: {path}")
            order.append(path)

    for name in CAN_MODULES:
        visit(name)
    for name in OPTIONAL_MODULES:
        if name in deps or name in builtin:
            visit(name)
    return order


def available() -> tuple[bool, str]:
    """Whether a UML kernel, its CAN modules and the guest tools are present (no boot)."""
    try:
        kernel = find_kernel()
        _module_plan(kernel)
    except UmlError as exc:
        return False, str(exc)
    guest_path = os.environ.get("PATH", "") + ":/usr/sbin:/sbin:/usr/bin:/bin"
    missing = [t for t in GUEST_TOOLS if shutil.which(t, path=guest_path) is None]
    if missing:
        return False, ("missing guest tools: " + ", ".join(missing)
                       + " (apt-get install kmod iproute2 can-utils)")
    return True, f"UML {kernel.version} ({kernel.origin}: {kernel.binary})"


# --------------------------------------------------------------------------- running a guest


_INIT = """#!/bin/sh
# Guest init written by vehest_can.tools.uml: mount, load CAN, add vcan, run the command, power off.
PATH=/usr/sbin:/usr/bin:/sbin:/bin
export PATH
W={work}
setup() {{
    mount -t proc proc /proc && mount -t sysfs sysfs /sys || return 1
    [ -e /dev/null ] || mount -t devtmpfs devtmpfs /dev || return 1
    mkdir -p /dev/shm && mount -t tmpfs -o mode=1777 tmpfs /dev/shm || return 1
    for ko in {modules}; do insmod "$ko" || return 1; done
    ip link set lo up || return 1
    if ip link add mcast0 type dummy 2> /dev/null; then
        ip link set mcast0 multicast on up && ip route add 224.0.0.0/4 dev mcast0 || return 1
    fi
    for dev in {ifaces}; do
        ip link add dev "$dev" type vcan && ip link set "$dev" mtu 72 &&
            ip link set up "$dev" || return 1
    done
}}
if setup > "$W/setup.log" 2>&1; then
    : > "$W/ready"
    if cd {cwd}; then
        env -i {env} /bin/sh "$W/command.sh" < /dev/null > "$W/stdout" 2> "$W/stderr"
        echo $? > "$W/rc"
    else
        echo "vehest_can.tools.uml: cannot cd to "{cwd} > "$W/stderr"
        echo 125 > "$W/rc"
    fi
fi
sync
poweroff -f > /dev/null 2>&1
echo o > /proc/sysrq-trigger
"""


def _console_tail(text: str, lines: int = 40) -> str:
    keep = [ln for ln in text.splitlines() if not ln.startswith(" [<")]  # drop stack addresses
    return "\n".join(keep[-lines:])


def _read(path: Path) -> str:
    try:
        return path.read_bytes().decode("utf-8", errors="replace")
    except FileNotFoundError:
        return ""


def _kill_tree(proc: subprocess.Popen) -> None:
    """SIGKILL the UML process group (the kernel process and its guest-process helpers)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()


def run(cmd: str, *, timeout: float = 120.0, env: dict[str, str] | None = None,
        cwd: str | os.PathLike | None = None, interfaces=("vcan0",), mem: str = "512M",
        workdir: str | os.PathLike | None = None, kernel: UmlKernel | None = None) -> UmlResult:
    """Boot UML, bring up ``interfaces`` (vcan, MTU 72), run ``cmd`` with ``/bin/sh`` as root.

    ``cwd`` (default: the current directory) and the host variables in CARRIED_ENV, updated by
    ``env``, are the command's working directory and its whole environment. ``timeout`` bounds
    the whole boot-run-poweroff in seconds; past it the UML process tree is killed and
    UmlTimeout raised. Files go to ``workdir`` if given (kept), else to a temporary directory
    removed after a successful run and kept (and named in the error) after a failed one.

    Returns the command's exit status and output; raises UmlError when the guest cannot boot
    or set up CAN (the message carries the console tail).
    """
    if not isinstance(cmd, str) or not cmd.strip():
        raise UmlError("run() needs a non-empty shell command line")
    if timeout <= 0:
        raise UmlError(f"timeout must be > 0 s, got {timeout}")
    ifaces = (interfaces,) if isinstance(interfaces, str) else tuple(interfaces)
    for name in ifaces:
        if not _IFACE_RE.match(name):
            raise UmlError(f"bad interface name {name!r}")
    if not re.match(r"^\d+[KMG]$", mem):
        raise UmlError(f"mem must look like 512M, got {mem!r}")
    if workdir is not None and re.search(r'[\s"]', os.path.abspath(os.fspath(workdir))):
        raise UmlError(f"workdir {os.fspath(workdir)!r} must not contain whitespace or quotes "
                       "(its path goes on the UML kernel command line)")
    kernel = kernel or find_kernel()
    modules = _module_plan(kernel)
    cwd = os.path.abspath(os.fspath(cwd) if cwd is not None else os.getcwd())
    if not os.path.isdir(cwd):
        raise UmlError(f"cwd {cwd} is not a directory")

    guest_env = {k: os.environ[k] for k in CARRIED_ENV if k in os.environ}
    guest_env.update(env or {})
    for key, value in guest_env.items():
        if not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", key) or not isinstance(value, str):
            raise UmlError(f"bad environment entry {key!r}={value!r}")
    guest_env["PATH"] = guest_env.get("PATH", "/usr/bin:/bin") + ":/usr/sbin:/sbin"

    keep = workdir is not None
    work = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="vehest-uml-"))
    work = work.resolve()
    work.mkdir(parents=True, exist_ok=True)
    for stale in ("ready", "rc", "stdout", "stderr", "setup.log", "console.log"):
        (work / stale).unlink(missing_ok=True)
    (work / "command.sh").write_text(cmd + "\n")
    init = work / "init.sh"
    init.write_text(_INIT.format(
        work=shlex.quote(str(work)),
        modules=" ".join(shlex.quote(str(m)) for m in modules),
        ifaces=" ".join(ifaces),
        cwd=shlex.quote(cwd),
        env=" ".join(shlex.quote(f"{k}={v}") for k, v in guest_env.items()),
    ))
    init.chmod(0o755)

    # UML backs its memory with an unlinked file in $TMPDIR or /dev/shm; keep it on a
    # file system with room for it.
    host_env = dict(os.environ)
    need = int(mem[:-1]) * {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}[mem[-1]]
    try:
        shm_ok = shutil.disk_usage("/dev/shm").free > need
    except OSError:
        shm_ok = False
    if not shm_ok and "TMPDIR" not in host_env:
        host_env["TMPDIR"] = str(work)
    argv = [str(kernel.binary), f"mem={mem}", "rootfstype=hostfs", "rootflags=/", "rw",
            f"init={init}", f"uml_dir={work}", f"umid=vehest{os.getpid()}-{time.monotonic_ns()}",
            "con=null", "con0=null,fd:1"]

    console_path = work / "console.log"
    start = time.monotonic()
    boot_seconds = float("nan")
    with open(console_path, "wb") as console:
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=console,
                                stderr=subprocess.STDOUT, env=host_env, start_new_session=True)
        try:
            while True:
                try:
                    proc.wait(timeout=0.05)
                    break
                except subprocess.TimeoutExpired:
                    pass
                now = time.monotonic()
                if boot_seconds != boot_seconds and (work / "ready").exists():
                    boot_seconds = now - start
                if now - start > timeout:
                    _kill_tree(proc)
                    stage = "the command" if (work / "ready").exists() else "boot/setup"
                    raise UmlTimeout(
                        f"UML run timed out after {timeout:g} s during {stage}; killed.",
                        console_tail=_console_tail(_read(console_path)), workdir=work)
        except BaseException:
            if proc.poll() is None:
                _kill_tree(proc)
            raise
        finally:
            # The guest's processes are host processes of the same group; none may outlive us.
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    total = time.monotonic() - start
    if boot_seconds != boot_seconds and (work / "ready").exists():
        boot_seconds = total

    console_text = _read(console_path)
    rc_text = _read(work / "rc").strip()
    if not rc_text:
        setup_log = _read(work / "setup.log").strip()
        why = ""
        if _FP_BUG in console_text:
            why = (f"\nThis UML kernel ({kernel.version}, {kernel.binary}) cannot run guest "
                   "processes on this CPU (its XSAVE area is too large for the kernel's "
                   "buffer); fetch a newer one: python -m vehest_can.tools.uml --fetch")
        raise UmlError(
            f"UML guest did not run the command (UML exit {proc.returncode})."
            + (f"\nGuest setup failed:\n{setup_log}" if setup_log else "") + why,
            console_tail=_console_tail(console_text), workdir=work)
    result = UmlResult(
        returncode=int(rc_text),
        stdout=_read(work / "stdout"),
        stderr=_read(work / "stderr"),
        console=console_text,
        console_log=console_path if keep else None,
        boot_seconds=boot_seconds,
        total_seconds=total,
    )
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    return result


# --------------------------------------------------------------------------- fetching a kernel


def _debian_mirror() -> str:
    """The Debian archive URI this host's apt already uses (main archive, not security)."""
    try:
        out = subprocess.run(
            ["apt-get", "indextargets", "--format", "$(REPO_URI)|$(LABEL)|$(TARGET_OF)"],
            capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        raise UmlError(f"cannot read apt's sources: {exc}") from exc
    for line in out.splitlines():
        uri, label, target = (line.split("|") + ["", "", ""])[:3]
        if label == "Debian" and target == "deb":
            return uri
    raise UmlError("apt has no Debian archive configured (run apt-get update first)")


def fetch_kernel(home: str | os.PathLike | None = None, *, suites=FETCH_SUITES,
                 force: bool = False, log=print) -> UmlKernel:
    """Download a newer Debian ``user-mode-linux`` (and the ``libc6`` it needs) into ``home``.

    Nothing is installed on the host: apt-get runs with its own sources list and state under
    ``home``, the packages are unpacked there with ``dpkg-deb -x``, and ``patchelf`` points
    the kernel at the unpacked C library. Needs apt-get, dpkg-deb, patchelf and
    debian-archive-keyring. Reuses an existing download unless ``force``.
    """
    home = Path(home) if home is not None else default_home()
    if not force:
        try:
            existing = _fetched_kernel(home)
        except UmlError:
            existing = None
        if existing is not None:
            log(f"UML {existing.version} already in {home}")
            return existing
    for tool in ("apt-get", "dpkg-deb", "patchelf"):
        if shutil.which(tool) is None:
            raise UmlError(f"fetch_kernel needs {tool} (apt-get install apt dpkg patchelf)")
    keyring = Path("/usr/share/keyrings/debian-archive-keyring.gpg")
    if not keyring.is_file():
        raise UmlError(f"{keyring} missing (apt-get install debian-archive-keyring)")
    mirror = _debian_mirror()
    home.mkdir(parents=True, exist_ok=True)
    apt = home / "apt"
    shutil.rmtree(apt, ignore_errors=True)
    for sub in ("lists/partial", "cache/archives/partial", "parts", "debs"):
        (apt / sub).mkdir(parents=True)
    opts = ["-q", "-o", f"Dir::Etc::SourceList={apt / 'sources.list'}",
            "-o", f"Dir::Etc::SourceParts={apt / 'parts'}",
            "-o", f"Dir::State::Lists={apt / 'lists'}", "-o", f"Dir::Cache={apt / 'cache'}",
            "-o", "APT::Sandbox::User=root"]

    def sh(argv, **kw):
        proc = subprocess.run(argv, capture_output=True, text=True, **kw)
        if proc.returncode != 0:
            raise UmlError(f"{' '.join(argv[:2])} failed: {(proc.stdout + proc.stderr)[-800:]}")
        return proc

    debs: list[Path] = []
    errors = []
    for suite in suites:  # one suite at a time: each index is ~10 MB
        (apt / "sources.list").write_text(f"deb [signed-by={keyring}] {mirror} {suite} main\n")
        log(f"apt-get update ({suite}) into {apt}")
        for old in (apt / "debs").glob("*.deb"):
            old.unlink()
        try:
            sh(["apt-get", *opts, "update"])
            sh(["apt-get", *opts, "download", f"user-mode-linux/{suite}", f"libc6/{suite}"],
               cwd=apt / "debs")
        except UmlError as exc:
            errors.append(f"{suite}: {exc}")
            continue
        debs = sorted((apt / "debs").glob("*.deb"))
        log(f"downloaded from {suite}: " + ", ".join(d.name for d in debs))
        break
    if not debs:
        raise UmlError("no suite had user-mode-linux + libc6:\n" + "\n".join(errors))

    staging = home / "root.new"
    shutil.rmtree(staging, ignore_errors=True)
    for deb in debs:
        sh(["dpkg-deb", "-x", str(deb), str(staging)])
    loaders = sorted(glob.glob(str(staging / "usr/lib/*-linux-gnu/ld-linux*.so.*")))
    if not loaders:
        raise UmlError(f"no dynamic loader in the unpacked libc6 under {staging}")
    loader = Path(loaders[0])
    final = home / "root"
    # Point the kernel at its libc where it will live after the rename below.
    sh(["patchelf", "--set-interpreter", str(final / loader.relative_to(staging)),
        "--set-rpath", str(final / loader.parent.relative_to(staging)),
        "--output", str(staging / "linux"), str(staging / "usr/bin/linux.uml")])
    shutil.rmtree(final, ignore_errors=True)
    staging.rename(final)
    shutil.rmtree(apt, ignore_errors=True)
    kernel = _fetched_kernel(home)
    if kernel is None:  # pragma: no cover - rename just made it
        raise UmlError(f"fetched kernel missing in {final}")
    log(f"UML {kernel.version} ready: {kernel.binary}")
    return kernel
