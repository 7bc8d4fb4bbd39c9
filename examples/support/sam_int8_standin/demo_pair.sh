#!/bin/bash
# objnerf demo, cold (empty embedding cache), fp32 then int8 (stand-in graph), main's binary 1776f85
for v in fp32 int8; do
  rm -rf /tmp/sam58/home_$v/cache /tmp/sam58/demo_$v
  echo "== $v start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  /usr/bin/time -v env OBJNERF_HOME=/tmp/sam58/home_$v /tmp/sam58/objnerf_main demo --out /tmp/sam58/demo_$v > /tmp/sam58/demo_$v.log 2> /tmp/sam58/demo_$v.err
  echo "== $v end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
done
