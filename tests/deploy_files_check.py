#!/usr/bin/env python3
"""deploy/ is consistent with the tools it runs and the metrics they export.

Every file under deploy/ is read:
  - YAML (.yaml, .yml) and JSON (.json) must parse (every document of a YAML stream);
  - every probecast tool invocation gives only flags that tool's --help (or its subcommand's)
    lists: in YAML, a `command` or `args` list (or string) whose first word is probecast-NAME
    (Compose services, Kubernetes containers); in shell scripts, every command whose word is
    probecast-NAME or $bin/probecast-NAME, with its continuation lines, up to the end of that
    command (| ; && || or a redirection);
  - every metric name in a PromQL expression (the Grafana dashboard's `expr`, the
    prometheus-adapter rules' seriesQuery and metricsQuery), a HorizontalPodAutoscaler's metric
    and any probecast_* / process_* name in a script is one the tools register: the names the
    code passes to MetricsText counter/gauge/histogram in server/ and relay/ (a histogram also
    as NAME_bucket, NAME_sum, NAME_count);
  - every job="..." a dashboard expression selects is a job of deploy/prometheus.yml and of
    the ServiceMonitors' job relabelings;
  - with nats-server installed, each NATS configuration (deploy/nats/, deploy/k8s/nats.conf)
    passes `nats-server -t` with stand-in secrets beside it;
  - with kubectl installed, deploy/k8s and deploy/k8s/monitoring build (`kubectl kustomize`,
    with stand-in secrets), every object in the namespace probecast.
A failure names the file, the tool or expression, and what is missing.

  tests/deploy_files_check.py BIN_DIR SOURCE_DIR WORK_DIR
"""
import json
import os
import re
import shlex
import shutil
import subprocess
import sys

import yaml

bin_dir, src, work = sys.argv[1], sys.argv[2], sys.argv[3]
deploy = os.path.join(src, "deploy")
failures = []
checked = {"flags": 0, "metrics": 0, "files": 0, "nats": 0}


def fail(where, what):
    failures.append(f"FAIL: {where}: {what}")


# --- The tools' flags, from their --help -----------------------------------------------------

help_cache = {}


def help_text(tool, sub=None):
    key = (tool, sub)
    if key not in help_cache:
        args = [os.path.join(bin_dir, tool)] + ([sub] if sub else []) + ["--help"]
        run = subprocess.run(args, capture_output=True, text=True)
        help_cache[key] = run.stdout + run.stderr
    return help_cache[key]


def options(tool, sub=None):
    """The --long option names a help lists (as tests/docs_flags_exist.sh reads them)."""
    names = set()
    for line in help_text(tool, sub).splitlines():
        m = re.match(r"^ +(-[^ ]+)", line)
        if not m:
            continue
        for part in m.group(1).split(","):
            part = re.sub(r"[={\[].*$", "", part)
            if part.startswith("--"):
                names.add(part)
    return names


def subcommands(tool):
    subs, inside = [], False
    for line in help_text(tool).splitlines():
        if re.match(r"^[A-Za-z]+:", line):
            inside = line.upper().startswith("SUBCOMMANDS:")
            continue
        if inside and re.match(r"^  [a-z]", line):
            subs.append(line.split()[0])
    return subs


def check_invocation(where, words):
    """words[0] names a probecast tool; every --flag after it must be in its help."""
    tool = os.path.basename(words[0])
    if not os.access(os.path.join(bin_dir, tool), os.X_OK):
        fail(where, f"{tool} is not a tool in {bin_dir}")
        return
    sub = None
    if len(words) > 1 and words[1] in subcommands(tool):
        sub = words[1]
    known = options(tool, sub)
    if not known:
        fail(where, f"`{tool} {sub or ''} --help` lists no options")
        return
    for w in words[1:]:
        m = re.match(r"^(--[a-z0-9][a-z0-9-]*)(=.*)?$", w)
        if not m:
            continue
        checked["flags"] += 1
        if m.group(1) not in known:
            fail(where, f"{m.group(1)} is given to {tool}{' ' + sub if sub else ''}, "
                 f"but its --help does not list it")


TOOL = re.compile(r"^(?:\$\{?bin\}?/)?(probecast-[a-z]+)$")


def yaml_invocations(path, node, trail):
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("command", "args"):
                words = value if isinstance(value, list) else (
                    shlex.split(value) if isinstance(value, str) else [])
                words = [str(w) for w in words]
                if words and TOOL.match(os.path.basename(words[0])):
                    check_invocation(f"{path} ({'/'.join(trail)})", words)
            yaml_invocations(path, value, trail + [str(key)])
    elif isinstance(node, list):
        for i, item in enumerate(node):
            yaml_invocations(path, item, trail + [str(i)])


def shell_invocations(path, text):
    # Logical lines: a trailing backslash joins the next; comments go.
    lines, pending, first = [], "", 0
    for number, raw in enumerate(text.splitlines(), 1):
        if not pending:
            first = number
        line = re.sub(r"(^|\s)#.*$", "", raw)
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        lines.append((first, pending + line))
        pending = ""
    for number, line in lines:
        try:
            words = shlex.split(line, comments=False, posix=True)
        except ValueError:
            words = line.split()
        for i, w in enumerate(words):
            m = TOOL.match(w)
            # A function definition (NAME() {...}) or a test of the file ([[ -x ... ]]) is not a
            # call; a call's flags end where its command does.
            if not m or (i > 0 and words[i - 1] in ("-x", "-f")):
                continue
            call = [m.group(1)]
            for rest in words[i + 1:]:
                if rest in ("|", "||", "&&", ";", "&", "}") or rest.startswith((">", "<", "2>")):
                    break
                call.append(rest)
            check_invocation(f"{path}:{number}", call)


# --- The metrics the tools register ----------------------------------------------------------

registered = set()
for folder in ("server", "relay"):
    for name in sorted(os.listdir(os.path.join(src, folder))):
        if not name.endswith(".cpp"):
            continue
        code = open(os.path.join(src, folder, name), encoding="utf-8").read()
        for kind, metric in re.findall(r"\.(counter|gauge|histogram)\(\s*\"([a-zA-Z_:][a-zA-Z0-9_:]*)\"",
                                       code):
            registered.add(metric)
            if kind == "histogram":
                registered.update({metric + "_bucket", metric + "_sum", metric + "_count"})
if len(registered) < 20:
    fail("server/, relay/", f"only {len(registered)} metric registrations found: the pattern "
         "this check reads them with no longer matches the code")

PROMQL_WORDS = {"by", "without", "on", "ignoring", "group_left", "group_right", "bool", "and",
                "or", "unless", "offset", "inf", "nan"}


def promql_metrics(expr):
    """Metric names an expression selects: identifiers that are neither functions, keywords,
    label matchers, grouping labels, durations nor strings."""
    e = re.sub(r'"(?:[^"\\]|\\.)*"', '""', expr)
    e = re.sub(r"'(?:[^'\\]|\\.)*'", "''", e)
    e = re.sub(r"<<[^>]*>>", " ", e)  # prometheus-adapter's templates
    e = re.sub(r"\{[^}]*\}", " ", e)
    e = re.sub(r"\[[^\]]*\]", " ", e)
    e = re.sub(r"\b(by|without|on|ignoring|group_left|group_right)\s*\([^)]*\)", " ", e)
    names = []
    for m in re.finditer(r"[a-zA-Z_:][a-zA-Z0-9_:]*", e):
        after = e[m.end():].lstrip()
        if after.startswith("(") or m.group(0).lower() in PROMQL_WORDS:
            continue
        if m.start() > 0 and (e[m.start() - 1].isdigit() or e[m.start() - 1] == "."):
            continue  # 1e3, 0.5
        names.append(m.group(0))
    return names


def check_metric(where, name):
    checked["metrics"] += 1
    if name not in registered:
        fail(where, f"metric {name} is not registered by server/ or relay/")


def check_expr(where, expr, template=False):
    """template: a prometheus-adapter metricsQuery, whose series is <<.Series>>."""
    names = promql_metrics(expr)
    if not names and not template:
        fail(where, f"no metric found in `{expr}`")
    for name in names:
        check_metric(where, name)


# --- Walk deploy/ ------------------------------------------------------------------------------

dashboard_jobs, scrape_jobs, monitor_jobs = set(), set(), set()


def walk_json(path, node, panel="?"):
    if isinstance(node, dict):
        panel = node.get("title", panel) if "targets" in node else panel
        if isinstance(node.get("expr"), str):
            check_expr(f"{path} (panel \"{panel}\", query {node.get('refId', '?')})", node["expr"])
            dashboard_jobs.update(re.findall(r'job="([^"]+)"', node["expr"]))
        for value in node.values():
            walk_json(path, value, panel)
    elif isinstance(node, list):
        for item in node:
            walk_json(path, item, panel)


def walk_yaml(path, doc):
    if not isinstance(doc, dict):
        return
    kind = doc.get("kind")
    if kind == "HorizontalPodAutoscaler":
        for metric in doc.get("spec", {}).get("metrics", []):
            for source in ("pods", "object", "external"):
                name = metric.get(source, {}).get("metric", {}).get("name")
                if name:
                    check_metric(f"{path} (HorizontalPodAutoscaler)", name)
    if kind == "ServiceMonitor":
        for endpoint in doc.get("spec", {}).get("endpoints", []):
            for r in endpoint.get("relabelings", []):
                if r.get("targetLabel") == "job":
                    monitor_jobs.add(r.get("replacement"))
    for job in doc.get("scrape_configs", []) or []:
        scrape_jobs.add(job.get("job_name"))
    rules = doc.get("rules")
    if isinstance(rules, dict):
        for rule in rules.get("custom", []):
            for key in ("seriesQuery", "metricsQuery"):
                if key in rule:
                    check_expr(f"{path} (prometheus-adapter {key})", rule[key],
                               template=key == "metricsQuery")
            if rule.get("name", {}).get("as"):
                check_metric(f"{path} (prometheus-adapter name)", rule["name"]["as"])


for root, dirs, files in os.walk(deploy):
    dirs[:] = sorted(d for d in dirs if d not in ("secrets", "state"))
    for name in sorted(files):
        path = os.path.join(root, name)
        rel = os.path.relpath(path, src)
        text = open(path, encoding="utf-8").read()
        checked["files"] += 1
        if name.endswith((".yaml", ".yml")):
            try:
                docs = list(yaml.safe_load_all(text))
            except yaml.YAMLError as e:
                fail(rel, f"not valid YAML: {e}")
                continue
            for doc in docs:
                yaml_invocations(rel, doc, [])
                walk_yaml(rel, doc)
        elif name.endswith(".json"):
            try:
                doc = json.loads(text)
            except json.JSONDecodeError as e:
                fail(rel, f"not valid JSON: {e}")
                continue
            walk_json(rel, doc)
        elif text.startswith("#!") and "sh" in text.splitlines()[0]:
            shell_invocations(rel, text)
            for metric in sorted(set(re.findall(r"\b(?:probecast|process)_[a-z0-9_]+\b", text))):
                check_metric(rel, metric)

for job in sorted(dashboard_jobs):
    if job not in scrape_jobs:
        fail("deploy/grafana", f'job="{job}" is not a job_name of deploy/prometheus.yml')
    if job not in monitor_jobs:
        fail("deploy/grafana", f'job="{job}" is not a job the ServiceMonitors of deploy/k8s set')

# --- NATS configurations -----------------------------------------------------------------------

nats_server = shutil.which("nats-server") or ("/usr/sbin/nats-server"
                                              if os.access("/usr/sbin/nats-server", os.X_OK) else None)
if nats_server:
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    # Stand-in secrets: nats-users.conf as deploy/make-secrets writes it, a throwaway key pair.
    etc = os.path.join(work, "etc")
    os.makedirs(etc)
    shutil.copy(os.path.join(deploy, "nats-relay-permissions.conf"), etc)
    with open(os.path.join(etc, "nats-users.conf"), "w") as f:
        f.write('authorization {\n  users = [\n    { user: field, password: "a" }\n'
                '    { user: relay, password: "b", permissions: { include '
                '"nats-relay-permissions.conf" } }\n  ]\n}\n')
    key, cert = os.path.join(etc, "nats-key.pem"), os.path.join(etc, "nats-cert.pem")
    made = subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt",
                           "ec_paramgen_curve:P-256", "-nodes", "-days", "1", "-subj", "/CN=nats",
                           "-keyout", key, "-out", cert], capture_output=True, text=True)
    if made.returncode != 0:
        fail("openssl", made.stderr.strip())
    shutil.copy(cert, os.path.join(etc, "ca.pem"))
    configs = [os.path.join(deploy, "nats", n) for n in sorted(os.listdir(os.path.join(deploy, "nats")))]
    configs.append(os.path.join(deploy, "k8s", "nats.conf"))
    # The copies name this folder where the containers mount /etc/nats and the store.
    for config in configs:
        text = open(config, encoding="utf-8").read().replace("/etc/nats/", etc + "/")
        with open(os.path.join(etc, os.path.basename(config)), "w") as f:
            f.write(text.replace("/var/lib/nats", os.path.join(work, "store")))
    for config in configs:
        name = os.path.basename(config)
        if name == "common.conf":
            continue  # included by each node's file
        run = subprocess.run([nats_server, "-c", os.path.join(etc, name), "-t"],
                             capture_output=True, text=True, env={**os.environ, "POD_NAME": "nats-0"})
        checked["nats"] += 1
        if run.returncode != 0:
            fail(os.path.relpath(config, src), "nats-server -t: " + (run.stderr + run.stdout).strip())

# --- Kustomizations ------------------------------------------------------------------------------

kubectl = shutil.which("kubectl")
if kubectl:
    # A copy of deploy/k8s with stand-in secrets: every file the generators name must exist.
    k8s = os.path.join(work, "k8s")
    shutil.rmtree(k8s, ignore_errors=True)
    shutil.copytree(os.path.join(deploy, "k8s"), k8s,
                    ignore=shutil.ignore_patterns("secrets"))
    os.makedirs(os.path.join(k8s, "secrets"))
    for generator in yaml.safe_load(open(os.path.join(k8s, "kustomization.yaml")))["secretGenerator"]:
        for f in generator["files"]:
            open(os.path.join(k8s, f), "w").write("stand-in\n")
    for folder in (k8s, os.path.join(k8s, "monitoring")):
        run = subprocess.run([kubectl, "kustomize", folder], capture_output=True, text=True)
        checked["kustomize"] = checked.get("kustomize", 0) + 1
        if run.returncode != 0:
            fail(os.path.relpath(folder, work), "kubectl kustomize: " + run.stderr.strip())
            continue
        for doc in yaml.safe_load_all(run.stdout):
            if doc and doc.get("kind") != "Namespace" and \
                    doc.get("metadata", {}).get("namespace") != "probecast":
                fail(os.path.relpath(folder, work),
                     f"{doc.get('kind')} {doc['metadata'].get('name')} is not in namespace probecast")

for line in failures:
    print(line)
if checked["flags"] == 0 or checked["metrics"] == 0:
    print(f"FAIL: found {checked['flags']} tool flags and {checked['metrics']} metric names in "
          "deploy/: the rules above find nothing")
    sys.exit(1)
if failures:
    sys.exit(1)
print(f"ok: {checked['files']} deploy/ files: {checked['flags']} tool flags in the tools' --help, "
      f"{checked['metrics']} metric names registered, {len(dashboard_jobs)} dashboard jobs scraped, "
      f"{checked['nats']} NATS configurations pass nats-server -t, "
      f"{checked.get('kustomize', 0)} kustomizations build")
