#!/usr/bin/env bash
# Make the files of fiberfem's secure mode (docs/security.md) with openssl: an identity
# CA and a permissions CA, identities (key + certificate) for the service and clients,
# the governance and permissions documents signed by the permissions CA, and one Cyclone
# DDS profile per identity that loads Debian's DDS Security plugins.
#
#   scripts/make_security.sh OUTDIR                      CAs + service, observer, operator
#   scripts/make_security.sh OUTDIR --client NAME --role observer|operator|service
#                                                        one more identity (repeatable)
#   scripts/make_security.sh OUTDIR --rogue              also an identity named "observer"
#                                                        signed by another CA (for tests)
#
# Idempotent: CAs and identities that exist are kept (so certificates already handed out
# stay valid); the governance, permissions and profiles are rewritten from the identities
# in OUTDIR (OUTDIR/identities/NAME/role) and signed again. No network. Private keys are
# unencrypted and readable by their owner only (umask 077): protect OUTDIR accordingly.
set -euo pipefail

usage() {
  sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}
die() {
  echo "make_security: $*" >&2
  exit 1
}

[[ $# -ge 1 && "$1" != -* ]] || usage
out="$1"
shift
declare -a new_names=() new_roles=()
rogue=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --client)
      [[ $# -ge 4 && "$3" == --role ]] || die "--client NAME must be followed by --role observer|operator|service"
      [[ "$2" =~ ^[A-Za-z0-9_-]+$ ]] || die "client name '$2': use letters, digits, '-' and '_' only"
      [[ "$2" != rogue ]] || die "client name 'rogue' is reserved for --rogue"
      case "$4" in observer | operator | service) ;; *) die "role '$4': use observer, operator or service" ;; esac
      new_names+=("$2")
      new_roles+=("$4")
      shift 4
      ;;
    --rogue) rogue=1 && shift ;;
    -h | --help) usage ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done

command -v openssl >/dev/null || die "openssl not found (Debian package openssl; scripts/setup.sh installs it)"

# Debian ships the three plugins with the library (package libddsc0debian, not on the
# default library path): find them with dpkg, or take FIBERFEM_DDS_SECURITY_DIR.
plugin_dir="${FIBERFEM_DDS_SECURITY_DIR:-}"
if [[ -z "$plugin_dir" ]]; then
  auth_so="$(dpkg -L libddsc0debian 2>/dev/null | grep '/libdds_security_auth\.so$' | head -n1 || true)"
  plugin_dir="$(dirname "${auth_so:-/nonexistent/x}")"
fi
for p in auth ac crypto; do
  [[ -f "$plugin_dir/libdds_security_$p.so" ]] ||
    die "Cyclone DDS Security plugin libdds_security_$p.so not found in '$plugin_dir' (Debian package libddsc0debian; or set FIBERFEM_DDS_SECURITY_DIR)"
done

umask 077
mkdir -p "$out"
out="$(cd "$out" && pwd)"
mkdir -p "$out/ca" "$out/identities" "$out/profiles"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
template="$here/configs/dds/secure-template.xml"
[[ -f "$template" ]] || die "profile template $template missing"

days=3650
# Subjects as DDS Security compares them: the certificate's subject in RFC 2253 form.
# Cyclone 0.10.2 compares a permissions subject_name with the certificate's name by
# comma-separated parts without trimming: no spaces after the commas.
subject_of() { echo "CN=$1,O=fiberfem,C=NL"; }
subj_arg() { echo "/C=NL/O=fiberfem/CN=$1"; }

# A self-signed CA (EC P-256), kept if it exists.
make_ca() {  # DIR BASENAME CN
  local key="$1/$2.key" pem="$1/$2.pem"
  [[ -f "$key" && -f "$pem" ]] && return 0
  openssl ecparam -name prime256v1 -genkey -noout -out "$key"
  openssl req -x509 -new -sha256 -key "$key" -days "$days" -subj "/C=NL/O=fiberfem/CN=$3" -out "$pem" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature"
  echo "make_security: made CA $pem"
}

# An identity (EC P-256 key, certificate signed by CA), kept if it exists.
make_identity() {  # DIR CN CA_PEM CA_KEY
  local dir="$1"
  mkdir -p "$dir"
  [[ -f "$dir/key.pem" && -f "$dir/cert.pem" ]] && return 0
  openssl ecparam -name prime256v1 -genkey -noout -out "$dir/key.pem"
  openssl req -new -sha256 -key "$dir/key.pem" -subj "$(subj_arg "$2")" -out "$dir/req.csr"
  printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n' >"$dir/ext.cnf"
  openssl x509 -req -sha256 -in "$dir/req.csr" -CA "$3" -CAkey "$4" -CAcreateserial -days "$days" \
    -extfile "$dir/ext.cnf" -out "$dir/cert.pem" 2>/dev/null
  rm -f "$dir/req.csr" "$dir/ext.cnf"
  echo "make_security: made identity $dir/cert.pem ($(subject_of "$2"))"
}

# One CA issues identities, another signs governance and permissions: who may join and
# what each may do are separate authorities (docs/security.md).
make_ca "$out/ca" identity_ca "fiberfem identity CA"
make_ca "$out/ca" permissions_ca "fiberfem permissions CA"

set_role() {  # NAME ROLE
  make_identity "$out/identities/$1" "$1" "$out/ca/identity_ca.pem" "$out/ca/identity_ca.key"
  echo "$2" >"$out/identities/$1/role"
}
for n in service observer operator; do
  [[ -f "$out/identities/$n/role" ]] || set_role "$n" "$n"
done
for i in "${!new_names[@]}"; do set_role "${new_names[$i]}" "${new_roles[$i]}"; done

# Governance: one rule for every domain. Only authenticated participants join (and only
# with valid permissions); discovery, liveliness and every RTPS message are encrypted; the
# fiberfem topics are read- and write-controlled, their discovery, metadata and data
# encrypted.
cat >"$out/governance.xml" <<'EOF'
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains>
        <id_range><min>0</min><max>230</max></id_range>
      </domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>ENCRYPT</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>fiberfem_*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF

# Permissions: one grant per identity, by role.
#   service   publishes topology, state, status, acks, circulation; subscribes to commands
#   observer  subscribes to topology, state, status, circulation
#   operator  the observer's, plus publishes commands and subscribes to acks
topics_xml() {
  local t
  for t in "$@"; do printf '            <topic>%s</topic>\n' "$t"; done
}
rule_xml() {  # KIND(publish|subscribe) TOPIC...
  local kind="$1"
  shift
  printf '        <%s>\n          <topics>\n%s\n          </topics>\n        </%s>\n' "$kind" "$(topics_xml "$@")" "$kind"
}
not_after="$(openssl x509 -in "$out/ca/identity_ca.pem" -noout -enddate | cut -d= -f2)"
not_after="$(date -u -d "$not_after" +%Y-%m-%dT%H:%M:%S)"
{
  cat <<'EOF'
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
EOF
  for dir in "$out"/identities/*/; do
    name="$(basename "$dir")"
    role="$(cat "$dir/role")"
    printf '    <grant name="fiberfem_%s">\n      <subject_name>%s</subject_name>\n' "$name" "$(subject_of "$name")"
    printf '      <validity><not_before>2020-01-01T00:00:00</not_before><not_after>%s</not_after></validity>\n' "$not_after"
    printf '      <allow_rule>\n        <domains><id_range><min>0</min><max>230</max></id_range></domains>\n'
    case "$role" in
      service)
        rule_xml publish fiberfem_mesh_topology fiberfem_mesh_state fiberfem_status fiberfem_command_ack fiberfem_circulation
        rule_xml subscribe fiberfem_command
        ;;
      observer)
        rule_xml subscribe fiberfem_mesh_topology fiberfem_mesh_state fiberfem_status fiberfem_circulation
        ;;
      operator)
        rule_xml publish fiberfem_command
        rule_xml subscribe fiberfem_mesh_topology fiberfem_mesh_state fiberfem_status fiberfem_command_ack fiberfem_circulation
        ;;
      *) die "identity $name has an unknown role '$role' in $dir/role" ;;
    esac
    printf '      </allow_rule>\n      <default>DENY</default>\n    </grant>\n'
  done
  printf '  </permissions>\n</dds>\n'
} >"$out/permissions.xml"

# Signed as DDS Security expects: S/MIME, text mode, by the permissions CA.
for doc in governance permissions; do
  openssl smime -sign -text -in "$out/$doc.xml" -out "$out/$doc.p7s" \
    -signer "$out/ca/permissions_ca.pem" -inkey "$out/ca/permissions_ca.key"
done

write_profile() {  # NAME IDENTITY_DIR IDENTITY_CA
  sed -e "s|@PLUGIN_DIR@|$plugin_dir|g" -e "s|@IDENTITY_CA@|$3|g" -e "s|@CERTIFICATE@|$2/cert.pem|g" \
    -e "s|@PRIVATE_KEY@|$2/key.pem|g" -e "s|@PERMISSIONS_CA@|$out/ca/permissions_ca.pem|g" \
    -e "s|@GOVERNANCE@|$out/governance.p7s|g" -e "s|@PERMISSIONS@|$out/permissions.p7s|g" "$template" \
    >"$out/profiles/$1.xml"
}
for dir in "$out"/identities/*/; do
  name="$(basename "$dir")"
  write_profile "$name" "$out/identities/$name" "$out/ca/identity_ca.pem"
done

# A rogue identity for tests: the observer's name, signed by a CA the others do not
# trust, with the real permissions (as if stolen): only authentication can stop it.
if [[ $rogue == 1 ]]; then
  mkdir -p "$out/rogue"
  make_ca "$out/rogue" rogue_ca "rogue CA"
  make_identity "$out/rogue/identity" observer "$out/rogue/rogue_ca.pem" "$out/rogue/rogue_ca.key"
  write_profile rogue "$out/rogue/identity" "$out/rogue/rogue_ca.pem"
fi

# Profiles and documents are not secret; keys stay owner-only.
chmod 644 "$out"/profiles/*.xml "$out"/*.xml "$out"/*.p7s "$out"/ca/*.pem
chmod 755 "$out" "$out/profiles"
echo "make_security: $out: profiles for$(for f in "$out"/profiles/*.xml; do printf ' %s' "$(basename "$f" .xml)"; done)"
echo "make_security: use CYCLONEDDS_URI=file://$out/profiles/NAME.xml"
