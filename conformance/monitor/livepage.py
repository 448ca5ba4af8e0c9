"""``monitor --http``: the live page, one self-contained HTML document (no build step, no CDN).

The page is rendered in the active language (``--lang``); its script opens
``events`` (server-sent events) and redraws from each snapshot
(:meth:`~.livestate.Board.snapshot`): the connections, sessions, frames and rates, a
latency plot (inline SVG), the live alarms, the findings' root causes, and links to the
ring's pcapng files and the reports. The first time an active alarm is drawn the script
notes the moment in ``window.firstAlarmAt`` (milliseconds since the epoch), which the
headless-browser test reads.
"""

from __future__ import annotations

import html
import json

from ..i18n import _, current

__all__ = ["page"]

_TEMPLATE = """<!DOCTYPE html>
<html lang="__LANG__">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>
body{font:14px/1.4 system-ui,sans-serif;margin:1em;color:#222;background:#fafafa}
h1{font-size:1.3em;margin:.2em 0}h2{font-size:1.05em;margin:1em 0 .3em}
table{border-collapse:collapse;margin:.2em 0}td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}
th{background:#eee}.num{text-align:right}#status{color:#666}
.alarm.active{background:#fdd;font-weight:bold}.alarm.cleared{color:#777}
.FAIL{color:#b00}.NON-STRICT{color:#a60}.INCONCLUSIVE{color:#555}
svg{background:#fff;border:1px solid #ccc}
</style>
</head>
<body>
<h1>__TITLE__</h1>
<div id="status">__WAITING__</div>
<h2>__ALARMS__</h2><div id="alarms"></div>
<h2>__SUMMARY__</h2><table id="summary"></table>
<h2>__LATENCY__</h2>
<svg id="plot" width="640" height="160" viewBox="0 0 640 160" role="img" aria-label="__LATENCY__"></svg>
<div id="legend"></div>
<h2>__OPEN__</h2><table id="conns"></table>
<h2>__FINDINGS__</h2><div id="findings"></div>
<h2>__FILES__</h2><div id="files"></div>
<script>
"use strict";
const L = __LABELS__;
window.firstAlarmAt = null;
function esc(s){return String(s).replace(/[&<>"']/g,c=>({"&":"&amp;","<":"&lt;",">":"&gt;","\\"":"&quot;","'":"&#39;"}[c]));}
function fmt(v){return v===null||v===undefined?"-":(typeof v==="number"?v.toLocaleString():esc(v));}
function rows(id, head, body){
  document.getElementById(id).innerHTML="<tr>"+head.map(h=>"<th>"+esc(h)+"</th>").join("")+"</tr>"+
    body.map(r=>"<tr>"+r.map(c=>"<td>"+c+"</td>").join("")+"</tr>").join("");
}
function plot(hist){
  const svg=document.getElementById("plot"), W=640, H=160;
  const series=[[1,"#06c",L.pose_p50],[2,"#c60",L.pose_p99],[3,"#090",L.command_p50]];
  let max=1;
  for(const h of hist){for(const [i] of series){if(h[i]!==null&&h[i]>max)max=h[i];}}
  let out="";
  for(const [i,color] of series){
    const pts=hist.map((h,k)=>h[i]===null?null:[(k/(Math.max(hist.length-1,1)))*(W-10)+5,H-5-(h[i]/max)*(H-20)])
      .filter(p=>p!==null).map(p=>p[0].toFixed(1)+","+p[1].toFixed(1)).join(" ");
    if(pts)out+='<polyline fill="none" stroke="'+color+'" stroke-width="1.5" points="'+pts+'"/>';
  }
  out+='<text x="5" y="12" font-size="11">'+esc(max.toFixed(2))+' ms</text>';
  svg.innerHTML=out;
  document.getElementById("legend").innerHTML=series.map(s=>'<span style="color:'+s[1]+'">&#9632; '+esc(s[2])+'</span>').join(" &nbsp; ");
}
function draw(s){
  document.getElementById("status").textContent=s.now+" \\u00b7 "+s.listen+" \\u2192 "+s.upstream+" \\u00b7 "+s.elapsed_s+" s";
  const al=document.getElementById("alarms");
  if(!s.alarms.length){al.textContent=L.none;}
  else{al.innerHTML=s.alarms.map(a=>'<div class="alarm '+(a.active?"active":"cleared")+'" data-kind="'+esc(a.kind)+
    '" data-clause="'+esc(a.clause)+'">'+(a.active?"ALARM ":"#"+a.id+" ")+esc(a.side.toUpperCase()+" "+a.clause+" ["+a.kind+"] "+a.what)+
    (a.outcome?" \\u2014 "+esc(a.outcome):"")+" <small>"+esc(a.raised)+"</small></div>").join("");}
  if(s.alarms_active&&window.firstAlarmAt===null){window.firstAlarmAt=Date.now();}
  const c=s.connections, f=s.frames, lat=s.latency_ms;
  rows("summary",[L.what,L.value],[
    [esc(L.connections),fmt(c.open)+" / "+fmt(c.total)+" ("+esc(L.refused)+" "+fmt(c.refused)+")"],
    [esc(L.sessions),fmt(s.sessions)],
    [esc(L.frames),"robot \\u2192 box "+fmt(f.robot)+", box \\u2192 robot "+fmt(f.box)+" ("+fmt(f.packets)+" packets)"],
    [esc(L.rate),fmt(s.rates.poses_per_s)+" poses/s, "+fmt(s.rates.frames_per_s)+" frames/s"],
    [esc(L.latency),"command p50 "+fmt(lat.command.p50)+" p99 "+fmt(lat.command.p99)+" ms; poses p50 "+fmt(lat.pose.p50)+" p99 "+fmt(lat.pose.p99)+" ms"],
    [esc(L.injected),fmt(s.injected)]]);
  plot(s.history);
  rows("conns",["#","robot","box",L.role,"s",L.requests,L.answers,L.poses,L.waiting],
    s.open.map(o=>[fmt(o.number),esc(o.robot),esc(o.box),esc(o.role),fmt(o.open_s),fmt(o.requests),fmt(o.answers),fmt(o.poses),fmt(o.waiting)]));
  const fi=document.getElementById("findings");
  fi.innerHTML=s.findings.length?s.findings.map(r=>'<div class="finding '+esc(r.verdict)+'">'+esc(r.verdict+" "+r.side.toUpperCase()+" "+r.clause)+
    " \\u00d7"+fmt(r.count)+": "+esc(r.first)+"</div>").join(""):esc(L.none);
  document.getElementById("files").innerHTML=s.ring.map(r=>'<a href="'+esc(r.href)+'">'+esc(r.file)+'</a> ('+esc(L.from_frame)+" "+fmt(r.first_frame)+")").join("<br>")+
    "<br>"+s.reports.map(r=>'<a href="'+esc(r.href)+'">'+esc(r.file)+"</a>").join(" \\u00b7 ");
  document.body.dataset.version=s.version;
}
function connect(){
  const es=new EventSource("events");
  es.onmessage=e=>{try{draw(JSON.parse(e.data));}catch(err){document.getElementById("status").textContent=String(err);}};
  es.onerror=()=>{document.getElementById("status").textContent=L.lost;};
}
connect();
</script>
</body>
</html>
"""


def page(listen: str, upstream: str) -> bytes:
    """The page in the active language."""
    labels = {
        "connections": _("connections"), "sessions": _("sessions completed"), "frames": _("frames"),
        "latency": _("answer latency"), "rate": _("pose stream"), "injected": _("faults injected"),
        "none": _("none so far"), "what": "", "value": "", "refused": _("refused"),
        "role": _("role"), "requests": _("requests"), "answers": _("answers"), "poses": _("poses"),
        "waiting": _("waiting"), "from_frame": _("from frame"), "lost": _("connection to the monitor lost; retrying"),
        "pose_p50": _("poses p50"), "pose_p99": _("poses p99"), "command_p50": _("commands p50"),
    }
    title = f"isight-conformance monitor {listen} → {upstream}"
    parts = {
        "__LANG__": current(), "__TITLE__": html.escape(title), "__WAITING__": html.escape(_("waiting for data…")),
        "__ALARMS__": html.escape(_("alarms")), "__SUMMARY__": html.escape(_("the line")),
        "__LATENCY__": html.escape(_("answer latency")), "__OPEN__": html.escape(_("connections")),
        "__FINDINGS__": html.escape(_("root causes")), "__FILES__": html.escape(_("pcapng ring and reports")),
        "__LABELS__": json.dumps(labels, ensure_ascii=False).replace("</", "<\\/"),
    }
    text = _TEMPLATE
    for key, value in parts.items():
        text = text.replace(key, value)
    return text.encode("utf-8")
